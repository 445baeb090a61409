"""Exports of a run for other tools: RenderMan RIB (rib.py) and glTF 2.0 (gltf.py), from shared geometry."""
