"""isaac_runtime: the back end. IR -> plan -> step loop -> outputs."""
