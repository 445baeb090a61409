"""isaac: the application layer: the command line, watch, golden, sweeps, the language server."""
