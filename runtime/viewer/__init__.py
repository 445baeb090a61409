"""The viewer: a self-contained HTML page that plays a run (write.py), served live by `isaac watch` (serve.py)."""
from .write import render_html, render_live_html, viewer_data, write_viewer

__all__ = ["render_html", "render_live_html", "viewer_data", "write_viewer"]
