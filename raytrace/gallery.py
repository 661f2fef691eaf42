"""The gallery: every bundled scene rendered with its own method as a PNG preview, by one command.

    RAYTRACE_ASSETS=../shared/scenes python render.py gallery --out docs/gallery [--width 960] [SCENE ...]

Each scene keeps its camera's aspect at `width` pixels (960x480 for a 2:1 camera) and its [render]
method and spp; the PNG is `render --png`'s preview (neutral view, automatic exposure), written with
film.write_together (a temporary file renamed into place) and compressed with PNG's optimize pass.
A scene whose meshes are not on the asset path (RAYTRACE_ASSETS) is skipped with a `GalleryNote`
warning (one `warning:` line on the command line, like every other note). README.md's
gallery links the files, with the meshes' credits from the asset folder's SOURCES.md.
"""
from __future__ import annotations

import warnings
from pathlib import Path

from . import api
from .errors import UserError
from .output import film
from .scene.assets import bundled_scenes, find_asset


class GalleryNote(UserWarning):
    """A bundled scene left out of the gallery (its meshes are not on RAYTRACE_ASSETS)."""


def missing_asset(scene) -> str | None:
    """Why `scene` cannot be rendered here (the first mesh file not found, find_asset's message), or None."""
    for i, shape in enumerate(scene.shapes):
        if shape.kind == "mesh":
            try:
                find_asset(shape.params["mesh"], scene.path, f"shape[{i}].mesh")
            except UserError as exc:
                return str(exc)
    return None


def _png_writer(rgb8):
    """`write(tmp)` of an optimized 8-bit PNG, for film.write_together."""
    from PIL import Image as Picture

    return lambda tmp: Picture.fromarray(rgb8, "RGB").save(tmp, format="PNG", optimize=True)


def render_gallery(out: Path, width: int = 960, names=(), note=print, threads: int | None = None) -> list[Path]:
    """Render `names` (default: every bundled scene) into `out`/NAME.png, one `note` line per scene
    (its size, method, spp and time; a scene skipped is a GalleryNote warning instead); returns the
    files written. Every name, the width, the thread count and the output paths are checked before
    anything is created or rendered."""
    scenes = bundled_scenes()
    names = list(names) or sorted(scenes)
    for name in names:
        if name not in scenes:
            raise UserError(f"gallery: {name}: not a bundled scene; {api._did_you_mean(name, scenes)}"
                            f"choose from: {', '.join(sorted(scenes))}")
    api.render_options(None, width=width, threads=threads)  # a size or thread count that is not positive
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out}: exists and is not a folder; choose a folder path")
    for name in names:
        film.check_writable(out / f"{name}.png", "--out")
    with film.folders_for([out / "gallery.png"]):  # created now; removed again if nothing is written
        return _render_all(out, names, width, note, threads)


def _render_all(out: Path, names, width: int, note, threads) -> list[Path]:
    """The renders of `render_gallery`, its arguments checked, into the folder `out`."""
    written = []
    for name in names:
        scene = api.load(name)
        why = missing_asset(scene)
        if why is not None:
            warnings.warn(f"gallery: skipped {name}: {why}", GalleryNote, stacklevel=3)
            continue
        image = api.render(scene, width=width, threads=threads)  # the height keeps the camera's aspect
        h, w = image.array.shape[:2]
        path = out / f"{name}.png"
        film.write_together([(path, _png_writer(film.tonemap(image.array)))])
        bounds = image.bound_note()
        note(f"gallery: {name}: {w}x{h}, method {image.method_label}, {image.spp} spp, {image.seconds:.1f} s "
             f"(+{image.compile_seconds:.1f} s compile) -> {path}" + (f"; {bounds}" if bounds else ""))
        written.append(path)
    return written
