"""isaac_ir: what a scene means, shared by the front end and the engine: the IR, expressions and their evaluation,
units, source positions and diagnostics, mass properties, the mesh reader and the rules for reading a scene's files.
It imports neither the parser (isaac_lang) nor the engine (isaac_runtime)."""
