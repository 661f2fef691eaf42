"""Scenes from and for other tools: glTF 2.0 (`gltf.py`), Mitsuba 3 XML (`mitsuba.py`), pbrt-v4 (`pbrt.py`).

Importers and exporters only produce and consume the scene dict (the TOML file's structure,
docs/scene_format.md); unit and convention conversions live in these modules and nowhere else.
Each format module has

    read_scene(path: Path) -> dict          the scene dict, or UserError naming the file, the key and the fix
    export(raw: dict, out: Path, source: str, approximate: bool) -> list[Path]
                                            the files written (the scene and what it references)

Triangle meshes travel inline as `primitive = "triangles"` shapes (`vertices`, `faces`).
"""
from __future__ import annotations

import importlib
from pathlib import Path

from ..errors import UserError

IMPORTERS = {".gltf": "gltf", ".glb": "gltf", ".xml": "mitsuba", ".pbrt": "pbrt", ".pbrt.gz": "pbrt"}  # suffix -> module
FORMATS = ("gltf", "mitsuba", "pbrt")  # `render.py export --format`


def _module(name: str):
    return importlib.import_module(f"{__name__}.{name}")


def importer(path: Path) -> str | None:
    """The format module that reads `path` (by its suffix, `.pbrt.gz` too), or None (TOML)."""
    name = Path(path).name.lower()
    return next((IMPORTERS[s] for s in sorted(IMPORTERS, key=len, reverse=True) if name.endswith(s)), None)


def read_scene(path: Path) -> dict:
    """The scene dict of a glTF, Mitsuba 3 or pbrt-v4 file (chosen by its suffix)."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no such scene file; check the path")
    return _module(importer(path)).read_scene(path)


def export(raw: dict, fmt: str, out: Path, source: str, approximate: bool = False) -> list[Path]:
    """Write the scene dict `raw` (read from `source`) as `fmt` to `out`; returns the files written."""
    if fmt not in FORMATS:
        raise UserError(f"{source}: --format {fmt}: unknown format; use one of {', '.join(FORMATS)}")
    return _module(fmt).export(raw, Path(out), source, approximate)
