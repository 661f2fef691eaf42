"""Scenes from and for other tools: glTF 2.0 (`gltf.py`), Mitsuba 3 XML (`mitsuba.py`), pbrt-v4 (`pbrt.py`).

Importers and exporters only produce and consume the scene dict (the TOML file's structure,
docs/scene_format.md); unit and convention conversions live in these modules and nowhere else.
Each format module has

    read_scene(path: Path) -> dict          the scene dict, or UserError naming the file, the key and the fix
                                            (a format whose files name their cameras takes `camera=NAME` too)
    export(raw: dict, out: Path, source: str, approximate: bool) -> list[Path]
                                            the files written (the scene and what it references)

Triangle meshes travel inline as `primitive = "triangles"` shapes (`vertices`, `faces`). What an
importer approximates is said in notes (`report.ImportNote` warnings, grouped by kind); a scene read
without lights gets a warning with a lamp to add; a refused file names all its problems (`report`).
"""
from __future__ import annotations

import importlib
import inspect
from pathlib import Path

from ..errors import UserError
from . import report

IMPORTERS = {".gltf": "gltf", ".glb": "gltf", ".xml": "mitsuba", ".pbrt": "pbrt", ".pbrt.gz": "pbrt"}  # suffix -> module
FORMATS = ("gltf", "mitsuba", "pbrt")  # `render.py export --format`


def _module(name: str):
    return importlib.import_module(f"{__name__}.{name}")


def importer(path: Path) -> str | None:
    """The format module that reads `path` (by its suffix, `.pbrt.gz` too), or None (TOML)."""
    name = Path(path).name.lower()
    return next((IMPORTERS[s] for s in sorted(IMPORTERS, key=len, reverse=True) if name.endswith(s)), None)


def read_scene(path: Path, camera: str | None = None) -> dict:
    """The scene dict of a glTF, Mitsuba 3 or pbrt-v4 file (chosen by its suffix), with the camera
    named `camera` where the format names its cameras (None: the format's default camera)."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no such scene file; check the path")
    module = _module(importer(path))
    if camera is None:
        raw = module.read_scene(path)
    elif "camera" not in inspect.signature(module.read_scene).parameters:
        raise UserError(f"{path}: camera {camera!r} (--camera): this format's importer reads one camera and does "
                        "not choose by name; leave --camera out and set the view with --set camera.position=... "
                        "--set camera.look_at=...")
    else:
        raw = module.read_scene(path, camera=camera)
    return raw


def export(raw: dict, fmt: str, out: Path, source: str, approximate: bool = False) -> list[Path]:
    """Write the scene dict `raw` (read from `source`) as `fmt` to `out`; returns the files written."""
    if fmt not in FORMATS:
        raise UserError(f"{source}: --format {fmt}: unknown format; use one of {', '.join(FORMATS)}")
    return _module(fmt).export(raw, Path(out), source, approximate)


def warn_no_lights(raw: dict, source: str):
    """Warn, with a lamp to add by --set, when an imported scene (after its overrides) has no lights."""
    report.warn(filter(None, [report.no_lights(raw, source)]))
