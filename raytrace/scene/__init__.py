"""Scene files: the TOML schema (`format.py`), mesh loading and primitives (`meshes.py`), and where
mesh files and bundled scenes are found (`assets.py`)."""
