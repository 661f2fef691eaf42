"""The Python API: `render(scene, method=..., **params)` returns an `Image` (the CLI is a thin layer).

    import raytrace
    img = raytrace.render("scenes/box_room.toml", method="analytic", precision=1e-6, spp=4)
    img.array          # (H, W, 3) float64 linear radiance
    img.stats          # the method's statistics (e.g. the analytic method's path fractions)
    img.save("box.exr"); img.save("box.png")

`scene` is a TOML file path, the name of a bundled scene (`box_room`, `sibenik`, `bridge`,
`conference`: the repository's scenes/, installed with the package), a dict with the file's structure (SCENE_FORMAT.md), a parsed `Scene`,
or None for the built-in default scene. Keyword arguments other than the render options below are
the method's own parameters; a parameter the method does not read is an error (UserError).
"""
from __future__ import annotations

import copy
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import io
from .errors import UserError
from .scene.format import Scene


@dataclass
class Image:
    """A rendered image with what produced it."""
    array: np.ndarray  # (H, W, 3) float64
    scene: str
    method: str
    params: dict
    stats: dict
    seconds: float  # render wall time, compilation excluded
    compile_seconds: float
    spp: int
    seed: int
    crop: tuple | None = None
    volumetric_shadows: bool = False
    variance: np.ndarray | None = None  # (H, W, 3) variance of each pixel's estimate (stochastic methods)
    extra_header: dict = field(default_factory=dict)

    def header(self) -> dict:
        """EXR header attributes: scene, method, parameters, options, times and statistics."""
        out = {"scene": self.scene, "method": self.method, "spp": self.spp, "seed": self.seed,
               "crop": ",".join(map(str, self.crop)) if self.crop else "none",
               "volumetric_shadows": str(self.volumetric_shadows).lower(),
               "render_seconds": f"{self.seconds:.3f}", "compile_seconds": f"{self.compile_seconds:.3f}",
               "params": " ".join(f"{k}={v}" for k, v in self.params.items()),
               "created": time.strftime("%Y-%m-%dT%H:%M:%S")}
        out.update({f"stats.{k}": v for k, v in self.stats.items()})
        out.update(self.extra_header)
        return out

    def save(self, path, exposure: float | None = None):
        """Write `path`: linear float32 EXR (.exr, with variance channels for stochastic methods) or a
        tone-mapped PNG preview (.png; 99.5th percentile of luminance → white unless `exposure`)."""
        from . import film

        path = Path(path)
        if path.suffix.lower() == ".png":
            film.write_png(path, film.tonemap(self.array, exposure))
        elif path.suffix.lower() == ".exr":
            extra = {}
            if self.variance is not None:
                extra = {f"variance.{c}": self.variance[..., i] for i, c in enumerate("RGB")}
            film.write_exr(path, self.array, self.header(), extra)
        else:
            raise UserError(f"{path}: unknown image type; save to a .exr (linear float32) or .png (preview) path")


def load(scene=None, overrides=()) -> Scene:
    """A `Scene` from a path, a dict, a `Scene` (returned as is) or None (the built-in default)."""
    from .scene.format import scene_from_dict

    if isinstance(scene, Scene):
        if overrides:
            raise UserError("overrides apply to scene files and dicts, not to a parsed Scene; pass the file or dict")
        return scene
    raw, source, path = scene_dict(scene, overrides)
    return scene_from_dict(raw, source, path)


def scene_dict(scene=None, overrides=()) -> tuple[dict, str, Path | None]:
    """(raw, source, path): the scene dict (the TOML structure) of a path, a bundled scene's name, a
    dict or None (the built-in default), with the overrides applied; not yet validated."""
    import tomllib

    from .default_scene import DEFAULT_TOML
    from .scene.assets import bundled_scenes
    from .scene.format import apply_override, parse_override, read_toml

    if scene is None:
        raw, source, path = tomllib.loads(DEFAULT_TOML), "default scene", None
    elif isinstance(scene, dict):
        raw, source, path = copy.deepcopy(scene), "scene dict", None
    else:
        path = Path(scene)
        if not path.exists() and path.suffix == "" and str(scene) in bundled_scenes():
            path = bundled_scenes()[str(scene)]
        source = str(path)
        # glTF, Mitsuba 3 and pbrt-v4 files are read into the scene dict by raytrace.io
        raw = io.read_scene(path) if io.importer(path) else read_toml(path)
    for item in overrides:
        apply_override(raw, *parse_override(item, source), source)
    return raw, source, path


def check_positive(name, value):
    """Refuse a count (spp, width, threads, ...) that is given but not a positive integer."""
    if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value <= 0):
        raise UserError(f"--{name} {value}: must be a positive integer; give a value of at least 1")


def apply_camera_options(scene: Scene, spp=None, width=None, height=None, threads=None, seed=None) -> int:
    """Check the render options shared by every command, set the camera's spp and size from them,
    and return the seed (the scene's [render] seed when none is given)."""
    for name, v in (("spp", spp), ("width", width), ("height", height), ("threads", threads)):
        check_positive(name, v)
    seed = scene.render.get("seed", 0) if seed is None else seed
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise UserError(f"--seed {seed}: must be >= 0; give a non-negative integer")
    cam = scene.camera
    cam.spp, cam.width, cam.height = spp or cam.spp, width or cam.width, height or cam.height
    return seed


def _check_crop(crop, cam):
    x0, y0, x1, y1 = crop
    if not (0 <= x0 < x1 <= cam.width and 0 <= y0 < y1 <= cam.height):
        raise UserError(f"--crop {x0},{y0},{x1},{y1}: must lie inside the {cam.width}x{cam.height} image with "
                        "X0 < X1 and Y0 < Y1 (end exclusive)")
    return tuple(int(v) for v in crop)


# bytes per pixel a render holds at its peak: the float64 image (24), the float32 copies written to
# the EXR (24) and the PNG preview's bands; stochastic methods add the progressive sums of radiance
# and variance and the final variance with its EXR channels. Measured peak RSS growth of render.py
# render (benchmarks/memory_peak.py, 4096 x 2048, with --png): 51 B a pixel (analytic), 99 (montecarlo)
PIXEL_BYTES, VARIANCE_BYTES = 60, 60
MEMORY_SHARE = 0.8  # of the machine's physical memory a render may plan to use


def physical_memory() -> int:
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def check_memory(cam, crop, stochastic: bool, source: str, max_memory: float | None = None):
    """Refuse, before anything is allocated, an image whose arrays would not fit in the budget:
    `max_memory` GiB (--max-memory) if given, else MEMORY_SHARE of the machine's physical memory.
    The refusal gives the figure and the fixes, with the rows a --crop band may have."""
    if max_memory is not None and (isinstance(max_memory, bool) or not isinstance(max_memory, (int, float))
                                   or not 0.0 < max_memory < math.inf):
        raise UserError(f"--max-memory {max_memory}: must be a positive number of GiB, e.g. --max-memory 8")
    x0, y0, x1, y1 = crop or (0, 0, cam.width, cam.height)
    per_pixel = PIXEL_BYTES + (VARIANCE_BYTES if stochastic else 0)
    need = (x1 - x0) * (y1 - y0) * per_pixel
    if max_memory is None:
        limit = MEMORY_SHARE * physical_memory()
        budget = f"{limit / 2**30:.3g} GiB ({MEMORY_SHARE:.0%} of this machine's memory; --max-memory sets another)"
    else:
        limit = max_memory * 2**30
        budget = f"the --max-memory budget of {max_memory:g} GiB"
    if need > limit:
        rows = int(limit // ((x1 - x0) * per_pixel))
        band = (f"render it in bands of at most {rows} rows with --crop (e.g. --crop {x0},{y0},{x1},{y0 + rows})"
                if rows >= 1 else "render it in parts with --crop")
        raise UserError(f"{source}: camera {cam.width}x{cam.height}: the image needs about {need / 2**30:.3g} GiB, "
                        f"more than {budget}; lower camera.width / camera.height (--width, --height) or {band}")


def render(scene=None, method: str | None = None, *, spp: int | None = None, width: int | None = None,
           height: int | None = None, seed: int | None = None, threads: int | None = None, crop=None,
           volumetric_shadows: bool | None = None, shadow_spacing: float | None = None, passes: int | None = None, time_budget: float | None = None,
           target_error: float | None = None, checkpoint=None, checkpoint_interval: float = 0.0,
           progress=None, on_pass=None, overrides=(), prepared=None, client=None, max_memory: float | None = None,
           **params) -> Image:
    """Render `scene` with `method` (default: the scene's [render] method, else analytic).

    Render options: spp, width, height (override the camera), seed, threads, crop = (x0, y0, x1, y1)
    (end exclusive; the same samples as in the whole image), volumetric_shadows and shadow_spacing
    (radians between the visibility samples of the lit-interval search, raytrace/visibility.py); for stochastic
    methods the progressive options passes, time_budget, target_error, checkpoint (a file, resumed
    when it exists) and checkpoint_interval. `progress(done, total)` (tiles) and `on_pass(passes,
    error)` report progress; `overrides` are "key=value" strings as --set; `prepared` reuses a
    `renderer.prepare`d scene (geometry and accelerator) for repeated renders; `client`, a
    `dask.distributed.Client`, renders the tiles on its cluster (the same image); `max_memory` (GiB)
    is the budget the image's arrays must fit (default 80 % of physical memory). Every other
    keyword is a parameter of the method; the scene's [render] table supplies defaults for all of
    these."""
    from . import renderer
    from .methods import get_method
    from .scene.format import RENDER_OPTIONS
    from .visibility import SHADOW_SPACING

    scene = prepared.scene if prepared is not None else load(scene, overrides)
    source = str(scene.path or ("default scene" if scene.name == "default" else scene.name))
    seed = apply_camera_options(scene, spp, width, height, threads, seed)
    check_positive("passes", passes)
    for name, v in (("time-budget", time_budget), ("target-error", target_error)):
        if v is not None and not v > 0:
            raise UserError(f"--{name} {v}: must be positive; give a value above 0")
    if not checkpoint_interval >= 0.0:
        raise UserError(f"--checkpoint-interval {checkpoint_interval}: must be >= 0 seconds; 0 saves after every pass")
    cam = scene.camera
    m = get_method(method or scene.render.get("method", "analytic"))
    shadows = bool(scene.render.get("volumetric_shadows", False) if volumetric_shadows is None else volumetric_shadows)
    spacing = float(scene.render.get("shadow_spacing", SHADOW_SPACING) if shadow_spacing is None else shadow_spacing)
    given = {k: v for k, v in scene.render.items() if k not in RENDER_OPTIONS}
    given.update({k: v for k, v in params.items() if v is not None})
    crop = _check_crop(crop, cam) if crop is not None else None
    progressive = passes or time_budget or target_error or checkpoint
    if progressive and not m.stochastic:
        raise UserError(f"--method {m.name}: deterministic; --passes, --time-budget, --target-error and "
                        "--checkpoint need a stochastic method such as montecarlo")
    check_memory(cam, crop, m.stochastic, source, max_memory)
    prep = prepared if prepared is not None else renderer.prepare(scene)
    if m.stochastic:
        from .progressive import render_progressive

        result = render_progressive(prep, m.name, given, seed, passes=passes, time_budget=time_budget,
                                    target_error=target_error, checkpoint=Path(checkpoint) if checkpoint else None,
                                    checkpoint_interval=checkpoint_interval, threads=threads, on_pass=on_pass,
                                    source=source, crop=crop, volumetric_shadows=shadows, shadow_spacing=spacing,
                                    client=client, progress=progress)
    else:
        result = renderer.render(prep, m.name, given, seed, threads, progress=progress, source=source, crop=crop,
                                 volumetric_shadows=shadows, shadow_spacing=spacing, client=client)
    if np.any(np.isnan(result.image)):
        raise UserError(f"{source}: the render produced non-finite pixels; this is a bug, please report the scene")
    if not np.all(result.image < np.finfo(np.float32).max):
        raise UserError(f"{source}: {int(np.sum(~(result.image < np.finfo(np.float32).max)))} pixel channels exceed "
                        "float32's 3.4e38 (an EXR cannot hold them): lower the lights' intensity or the medium's "
                        "coefficients, or move the camera off the light it sits on")
    return Image(result.image, scene.name, result.method, result.params, result.stats, result.seconds,
                 result.compile_seconds, cam.spp, seed, crop, shadows, result.variance,
                 {"shadow_spacing": spacing} if shadows else {})
