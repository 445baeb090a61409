"""isaac: the application layer, the one place that imports both the front end (isaac_lang: text -> IR) and the
engine (isaac_runtime: IR -> plan -> run -> outputs): the command line, watch, live, golden, sweeps, exports and the
embedding API (isaac.api: a Simulation built from a scene file or text)."""


def installed_version() -> str:
    """The installed distribution's version (`isaac --version`, and what a golden records it was made with)."""
    try:
        from importlib.metadata import version

        return version("isaac")
    except Exception:  # not installed (a source tree on sys.path)
        return "unknown (not installed)"
