"""Mesh files (OBJ, PLY) as the Mitsuba and pbrt importers read them: vertices, triangles and the file's
own vertex normals, through trimesh."""
from __future__ import annotations

import numpy as np


def read_mesh(file, file_type: str):
    """(vertices (V, 3), faces (T, 3), the file's vertex normals (V, 3) or None) of a mesh file (a path or a
    binary file object): every object of the file, in order, vertices as written (process=False).

    trimesh keeps a file's normals (OBJ `vn`, PLY nx ny nz) in its cache on loading and computes them
    only when asked: normals found in the cache are the file's. (`force="mesh"` would drop them.)"""
    import trimesh

    loaded = trimesh.load(file, file_type=file_type, process=False)
    parts = list(loaded.geometry.values()) if isinstance(loaded, trimesh.Scene) else [loaded]
    parts = [g for g in parts if isinstance(g, trimesh.Trimesh)]
    if not parts:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), None
    offsets = np.cumsum([0] + [len(g.vertices) for g in parts])
    v = np.concatenate([np.asarray(g.vertices, float) for g in parts])
    f = np.concatenate([np.asarray(g.faces, np.int64) + o for g, o in zip(parts, offsets)])
    vn = None
    if all("vertex_normals" in g._cache for g in parts):
        vn = np.concatenate([np.asarray(g.vertex_normals, float) for g in parts])
        if vn.shape != v.shape or not np.all(np.isfinite(vn)):
            vn = None
    return v, f, vn
