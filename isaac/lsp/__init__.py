"""`isaac lsp`: a Language Server Protocol server for `.isaac` scenes, on pygls, over stdio.

It checks the scenes open in an editor with the front end (isaac_lang) as `isaac check` does, and answers
hover, go to definition, references, completion and the outline from the parse trees. It never imports the
engine (isaac_runtime): it checks scenes, it does not simulate them.

    from isaac.lsp import serve_stdio
    serve_stdio()
"""
from __future__ import annotations


def serve_stdio() -> int:
    """Run the server on stdin/stdout until the client says `exit`; 0 after a `shutdown` request, else 1 (as the
    protocol asks)."""
    from .server import serve

    return serve()
