"""The Python API: `render(scene, method=..., **params)` returns an `Image` (the CLI is a thin layer).

    import raytrace
    img = raytrace.render("scenes/box_room.toml", method="analytic", precision=1e-6, spp=4)
    img.array          # (H, W, 3) float64 linear radiance
    img.stats          # the method's statistics (e.g. the analytic method's path fractions)
    img.save("box.exr", "box.png")  # both or neither

`scene` is a TOML file path, the name of a bundled scene (`box_room`, `sibenik`, `bridge`,
`conference`: the repository's scenes/, installed with the package), a dict with the file's structure (SCENE_FORMAT.md), a parsed `Scene`,
or None for the built-in default scene. Keyword arguments other than the render options (the fields
of `RenderOptions`, raytrace/options.py, checked once by `render_options`) are the method's own
parameters; one the method does not read is an error (UserError), while one in the scene's [render]
table that it does not read is ignored with one `SceneDefaultNote` warning.
"""
from __future__ import annotations

import copy
import difflib
import math
import time
import warnings
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from . import error_bounds, io
from .errors import UserError, counted
from .options import MEMORY_SHARE, RenderOptions, physical_memory  # noqa: F401  (api.MEMORY_SHARE for callers)
from .scene.format import Scene

IGNORED = frozenset({"shadow_spacing"})  # accepted so that older scripts run; not read (the lit intervals are exact)
OPTION_NAMES = frozenset(f.name for f in fields(RenderOptions))


PREVIEW_WIDTH = 480  # pixels: the widest preview a notebook shows (Image._repr_png_)


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
    # (H, W, 3) float32 (rounded up): |array - exact| <= error_bound per pixel and channel, inf where no
    # bound is known; for a stochastic method its standard error instead (statistical, not a bound):
    # docs/error_bounds.md
    error_bound: np.ndarray | None = None
    auto: str | None = None  # method = "auto": its choice in words ("analytic", "quadrature (analytic: why not)")
    unbounded: float = 0.0  # the share of pixels whose error_bound is infinite in some channel (0 to 1)
    unbounded_reason: str = ""  # why, in a few words, where the render knows it (`unbounded_reason`)
    # the output layers asked for (rendering/aov.py): "depth" (H, W, 1), "normal", "albedo", "light0", ...,
    # "emission" (H, W, 3); the light layers and emission sum to `array`
    layers: dict = field(default_factory=dict)

    @property
    def method_label(self) -> str:
        """The method as summaries name it: "analytic", or "auto → quadrature (analytic: ...)"."""
        return self.method if self.auto is None else f"auto → {self.auto}"

    def bound_note(self, always: bool = False) -> str:
        """The share of pixels without a finite error bound, with its reason: "1.5 % of pixels
        unbounded: ..."; "" when every pixel is bounded (unless `always`)."""
        if not self.unbounded:
            return "every pixel bounded" if always else ""
        return f"{_percent(self.unbounded)} of pixels unbounded" + (f": {self.unbounded_reason}" if self.unbounded_reason else "")

    def __repr__(self) -> str:
        height, width = self.array.shape[:2]
        return (f"Image({self.scene}: {width}x{height}, method {self.method_label}, {self.seconds:.2f} s, "
                f"{self.bound_note(always=True)})")

    def header(self) -> dict:
        """EXR header attributes: scene, method, parameters, options, times and statistics."""
        out = {"scene": self.scene, "method": self.method, "spp": self.spp, "seed": self.seed,
               "crop": ",".join(map(str, self.crop)) if self.crop else "none",
               "volumetric_shadows": str(self.volumetric_shadows).lower(),
               "render_seconds": f"{self.seconds:.3f}", "compile_seconds": f"{self.compile_seconds:.3f}",
               "params": " ".join(f"{k}={v}" for k, v in self.params.items()),
               "created": time.strftime("%Y-%m-%dT%H:%M:%S"), "unbounded_pixels": f"{self.unbounded:.6g}"}
        if self.unbounded_reason:
            out["unbounded_reason"] = self.unbounded_reason
        if self.auto is not None:
            out["method_choice"] = self.method_label
        out.update({f"stats.{k}": v for k, v in self.stats.items()})
        return out

    def layer(self, name: str) -> "Image":
        """The output layer `name` (a key of `layers`) as an Image of its own, to show or save (a
        depth layer in all three channels)."""
        if name not in self.layers:
            raise UserError(f"layer {name!r}: not in this render; it has {', '.join(self.layers) or 'no layers'} "
                            "(render with aov=[...] or --aov)")
        array = self.layers[name]
        return replace(self, array=np.repeat(array, 3, axis=-1) if array.shape[-1] == 1 else array,
                                   scene=f"{self.scene} ({name})", variance=None, error_bound=None, layers={},
                                   unbounded=0.0, unbounded_reason="")

    def _repr_png_(self) -> bytes:
        """A notebook's preview: the PNG (neutral view, automatic exposure) at most PREVIEW_WIDTH wide."""
        from io import BytesIO

        from PIL import Image as Picture

        from .output import film

        picture = Picture.fromarray(film.tonemap(self.array), "RGB")
        if picture.width > PREVIEW_WIDTH:
            height = max(1, round(picture.height * PREVIEW_WIDTH / picture.width))
            picture = picture.resize((PREVIEW_WIDTH, height), Picture.Resampling.BOX)
        buffer = BytesIO()
        picture.save(buffer, format="PNG")
        return buffer.getvalue()

    def _repr_html_(self) -> str:
        """The preview with a caption: scene, size, method, spp and render time."""
        import base64
        import html

        height, width = self.array.shape[:2]
        caption = (f"{self.scene}: {width}x{height}, method {self.method_label}, {self.spp} spp, {self.seconds:.2f} s "
                   f"(+{self.compile_seconds:.2f} s compile)" + (f", {self.bound_note()}" if self.unbounded else ""))
        data = base64.b64encode(self._repr_png_()).decode("ascii")
        return (f'<figure><img src="data:image/png;base64,{data}" alt="{html.escape(caption)}">'
                f"<figcaption>{html.escape(caption)}</figcaption></figure>")

    def save(self, *paths, exposure: float | None = None, view: str = "neutral"):
        """Write every path, all or nothing (each to a temporary file beside it, renamed once all are
        written): linear float32 EXR (.exr, with error_bound.R/G/B channels, the bound of the float32
        values, error_bounds.stored, variance channels for stochastic methods and the output layers'
        channels, rendering/aov.py: depth.Z, normal.X/Y/Z, albedo.R/G/B, light0.R/G/B, ..., emission.R/G/B) or an 8-bit
        PNG preview (.png) through `view`: "neutral" (Khronos PBR Neutral, highlights roll off
        and lamps keep their hue), "aces" (ACES 2.0's SDR view, which greys coloured lamps) or "standard"
        (the exact sRGB encode, clipping at 1). `exposure` is in stops (each doubles the radiance); None
        is automatic: the log-average luminance at middle grey for "neutral" and "aces", the 99.5th
        percentile of luminance at white for "standard"."""
        from .output import film
        from .output.view import check_exposure

        exposure, view = check_exposure(exposure), film.check_view(view)
        jobs = []
        for path in map(Path, paths):
            if path.suffix.lower() == ".png":
                jobs.append((path, film.png_writer(film.tonemap(self.array, exposure, view))))
            elif path.suffix.lower() == ".exr":
                extra = {}
                if self.error_bound is not None:
                    stored = error_bounds.stored(self.array, self.error_bound)
                    extra = {f"error_bound.{c}": stored[i] for i, c in enumerate("RGB")}
                if self.variance is not None:
                    extra.update({f"variance.{c}": self.variance[..., i] for i, c in enumerate("RGB")})
                if self.layers:
                    from .rendering.aov import exr_channels

                    extra.update(exr_channels(self.layers))
                jobs.append((path, film.exr_writer(self.array, self.header(), extra)))
            else:
                raise UserError(f"{path}: unknown image type; save to a .exr (linear float32) or .png (preview) path")
        film.write_together(jobs)


def _percent(share: float) -> str:
    """A share (0 to 1) as a percentage to a tenth: "1.5 %", "< 0.1 %" and "> 99.9 %" at the ends."""
    pct = 100.0 * share
    if share == 1.0:
        return "100 %"
    if pct < 0.1:
        return "< 0.1 %"
    return "> 99.9 %" if pct > 99.9 and share < 1.0 else f"{pct:.1f} %"


def load(scene=None, overrides=(), camera: str | None = None) -> Scene:
    """A `Scene` from a path, a dict, a `Scene` (returned as is) or None (the built-in default);
    `overrides` and `camera` as for `scene_dict`."""
    from .scene.format import scene_from_dict

    if isinstance(scene, Scene):
        if overrides or camera is not None:
            raise UserError("overrides and camera apply to scene files and dicts, not to a parsed Scene; pass the "
                            "file or dict")
        return scene
    raw, source, path = scene_dict(scene, overrides, camera)
    return scene_from_dict(raw, source, path)



def _plain(value):
    """A copy of a scene dict with numpy arrays and scalars as the lists and numbers of TOML (and
    tuples as lists), so that `render({"camera": {"position": np.array(...)}})` reads as TOML would."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return copy.deepcopy(value)

def scene_dict(scene=None, overrides=(), camera: str | None = None) -> tuple[dict, str, Path | None]:
    """(raw, source, path): the scene dict (the TOML structure) of a path, a bundled scene's name, a
    dict or None (the built-in default), with the overrides applied; not yet validated. `camera`
    names the camera of a file that names its cameras (glTF: a node's or a camera's name; raytrace.io);
    a TOML scene has one [camera], so a name given for it is refused."""
    import tomllib

    from .default_scene import DEFAULT_TOML
    from .scene.assets import bundled_scenes
    from .scene.format import apply_override, parse_override, read_toml

    if scene is None:
        raw, source, path = tomllib.loads(DEFAULT_TOML), "default scene", None
    elif isinstance(scene, dict):
        raw, source, path = _plain(scene), "scene dict", None
    else:
        path = Path(scene)
        if not path.exists() and path.suffix == "":
            if str(scene) not in bundled_scenes():
                raise UserError(f"{scene}: no such scene file or bundled scene; {_did_you_mean(str(scene), bundled_scenes())}"
                                f"give a scene file's path or a bundled scene: {', '.join(sorted(bundled_scenes()))}")
            path = bundled_scenes()[str(scene)]
        source = str(path)
        # glTF, Mitsuba 3 and pbrt-v4 files are read into the scene dict by raytrace.io
        raw = io.read_scene(path, camera) if io.importer(path) else read_toml(path)
    if camera is not None and not (path is not None and io.importer(path)):
        raise UserError(f"{source}: {_named('camera', camera)}: names a camera of a glTF file; this scene has one "
                        "[camera]: leave it out and change the view with camera.position and camera.look_at "
                        "(--set camera.position=[x, y, z])")
    for item in overrides:
        apply_override(raw, *parse_override(item, source), source)
    if path is not None and io.importer(path):  # after --set, which may add the lights a file lacks
        io.warn_no_lights(raw, source)
    return raw, source, path


def _did_you_mean(name: str, choices) -> str:
    """'did you mean "x"? ' for the choice closest to `name`, or '' when none is close."""
    close = difflib.get_close_matches(name, list(choices), n=1)
    return f'did you mean "{close[0]}"? ' if close else ""


def get_method(name: str, source: str):
    """The registered method `name`; UserError with the closest name and the list otherwise."""
    from .methods import get_method as registered, registry

    if name not in registry():
        raise UserError(f"{source}: method={name!r} (--method {name}): unknown method; {_did_you_mean(str(name), registry())}"
                        f"choose one of: {', '.join(registry())}")
    return registered(name)


def _named(key: str, value) -> str:
    """An option as messages name it: the API keyword and its value, with the command line's flag."""
    return f"{key}={value!r} (--{key.replace('_', '-')} on the command line)"


def _check_count(key: str, value):
    """Refuse a count (spp, width, threads, ...) that is given but not a positive integer."""
    if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value <= 0):
        raise UserError(f"{_named(key, value)}: must be a positive integer; give a value of at least 1")


def image_size(cam, width: int | None = None, height: int | None = None) -> tuple[int, int]:
    """(width, height) of a render of camera `cam`: both given, as given; one given, the other keeps
    the camera's aspect (rounded to the nearest integer, halves up, at least 1); neither, the camera's."""
    if width is not None and height is None:
        height = max(1, (2 * width * cam.height + cam.width) // (2 * cam.width))
    elif height is not None and width is None:
        width = max(1, (2 * height * cam.width + cam.height) // (2 * cam.height))
    return width or cam.width, height or cam.height


def render_options(scene: Scene | None, source: str = "render", **given) -> RenderOptions:
    """The checked `RenderOptions` of a render of `scene` from `given` keywords (its field names;
    None or absent: the scene's [render] value where it has one, else the default). Every value is
    checked here, once; the scene's camera takes the spp, width and height given (one of width and
    height alone keeps its aspect: `image_size`), and the crop must lie inside it (`scene` None: no
    [render] defaults, no camera, no crop)."""
    given = {k: v for k, v in given.items() if v is not None}
    table = scene.render if scene is not None else {}
    for key in ("spp", "width", "height", "threads", "passes"):
        _check_count(key, given.get(key))
    if scene is not None and ("width" in given or "height" in given):
        given["width"], given["height"] = image_size(scene.camera, given.get("width"), given.get("height"))
    for key in ("time_budget", "target_error"):
        if key in given and not given[key] > 0:
            raise UserError(f"{_named(key, given[key])}: must be positive; give a value above 0")
    if not given.get("checkpoint_interval", 0.0) >= 0.0:
        raise UserError(f"{_named('checkpoint_interval', given['checkpoint_interval'])}: must be >= 0 seconds; "
                        "0 saves after every pass")
    v = given.get("max_memory")
    if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 < v < math.inf):
        raise UserError(f"{_named('max_memory', v)}: must be a positive number of GiB, e.g. max_memory=8 "
                        "(--max-memory 8)")
    seed = given["seed"] = given.get("seed", table.get("seed", 0))
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise UserError(f"{_named('seed', seed)}: must be >= 0; give a non-negative integer")
    given["volumetric_shadows"] = bool(given.get("volumetric_shadows", table.get("volumetric_shadows", False)))
    if "checkpoint" in given:
        given["checkpoint"] = Path(given["checkpoint"])
    if "aov" in given or "aov" in table:
        from .rendering import aov

        named = _named("aov", given["aov"]) if "aov" in given else f"{source}: render.aov"
        given["aov"] = aov.check(given.get("aov", table.get("aov")), named)
        if given["aov"] and (given.get("passes") or given.get("time_budget") or given.get("target_error")
                             or given.get("checkpoint")):
            raise UserError(f"{named}: output layers are not kept across progressive passes; render them in one pass "
                            "(--spp) without --passes, --time-budget, --target-error or --checkpoint")
    options = RenderOptions(**given)
    if scene is not None:
        options.apply_camera(scene.camera)
    if options.crop is not None:
        options = replace(options, crop=_check_crop(options.crop, scene.camera))
    return options


def _check_crop(crop, cam):
    x0, y0, x1, y1 = crop
    if not (0 <= x0 < x1 <= cam.width and 0 <= y0 < y1 <= cam.height):
        raise UserError(f"{_named('crop', tuple(crop))}: must lie inside the {cam.width}x{cam.height} image with "
                        "x0 < x1 and y0 < y1 (end exclusive)")
    return tuple(int(v) for v in crop)


def executor(options: RenderOptions, client=None, source: str = "render"):
    """Where the tiles run: on the cluster of a `dask.distributed.Client` (rendering/distributed.py, imported
    only then), else on a pool of `options.threads` threads (renderer.Threads)."""
    from .rendering import renderer

    if client is None:
        return renderer.Threads(options.threads)
    if options.threads is not None:
        raise UserError(f"{source}: {_named('threads', options.threads)} applies to one machine; on a cluster "
                        "(client, --scheduler) every worker runs as many tiles as it has threads: remove it")
    from .rendering.distributed import Cluster

    return Cluster(client)


# bytes per pixel a render holds at its peak: the float64 image (24), its float32 error bound (12),
# the float32 copies written to the EXR (24, and 12 of the bound's channels) and the PNG preview's
# bands; stochastic methods add the progressive sums of radiance, variance and bound and the final
# variance with its EXR channels. Measured peak RSS growth of
# render.py render (benchmarks/image_memory.py, 4096 x 2048, with --png): 78 B a pixel (analytic),
# 116 (montecarlo)
PIXEL_BYTES, VARIANCE_BYTES = 90, 50
def check_memory(cam, crop, stochastic: bool, source: str, max_memory: float | None = None):
    """Refuse, before anything is allocated, an image whose arrays would not fit in the budget:
    `max_memory` GiB (checked by render_options) if given, else MEMORY_SHARE of the machine's physical memory.
    The refusal gives the figure and the fixes, with the rows a --crop band may have."""
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
        band = (f"render it in bands of at most {counted(rows, 'row')} with --crop "
                f"(e.g. --crop {x0},{y0},{x1},{y0 + rows})"
                if rows >= 1 else "render it in parts with --crop")
        raise UserError(f"{source}: camera {cam.width}x{cam.height}: the image needs about {need / 2**30:.3g} GiB, "
                        f"more than {budget}; lower camera.width / camera.height (--width, --height) or {band}")


class SceneDefaultNote(UserWarning):
    """A scene's [render] parameter that the chosen method does not read was left out."""


def table_params(scene: Scene) -> dict:
    """The method parameters of the scene's [render] table (the file's, with --set render.X edits)."""
    from .scene.format import RENDER_OPTIONS

    return {k: v for k, v in scene.render.items() if k not in RENDER_OPTIONS}


def scene_defaults(params: dict, method, source: str) -> dict:
    """The parameters among a scene's [render] `params` (`table_params`) that `method` reads. The ones it does not read (e.g. a quadrature scene's rtol when rendering
    with raymarch, or a stray rtol beside method = "analytic") are left out with one
    SceneDefaultNote, never refused: only a keyword or flag given explicitly is (resolve_params)."""
    unread = [k for k in params if k not in method.params]
    if unread:
        warnings.warn(f"{source}: [render] {', '.join(f'{k} = {params[k]!r}' for k in unread)}: not read by method "
                      f"{method.name}; ignored", SceneDefaultNote, stacklevel=3)
    return {k: v for k, v in params.items() if k not in unread}


def render(scene=None, method: str | None = None, *, overrides=(), camera: str | None = None, prepared=None,
           client=None, **kwargs) -> Image:
    """Render `scene` with `method` (default: the scene's [render] method, else "auto": analytic
    where it takes the scene, else quadrature, `choose_method`).

    Keywords named as `RenderOptions`' fields are render options (raytrace/options.py: spp, width,
    height, seed, threads, crop, volumetric_shadows, the progressive passes,
    time_budget, target_error, checkpoint and checkpoint_interval, max_memory, and the callbacks
    progress, on_pass, observer and notice); every other keyword is a parameter of the method. The scene's
    [render] table supplies defaults for both. Volumetric shadows are on unless volumetric_shadows=False
    or the scene's [render] turns them off. `overrides` are "key=value" strings as --set;
    `camera` names the camera of a glTF file (as --camera);
    `prepared` reuses a `renderer.prepare`d scene (geometry and accelerator) for repeated renders;
    `client`, a `dask.distributed.Client`, renders the tiles on its cluster (the same image)."""
    from .rendering import renderer

    scene = prepared.scene if prepared is not None else load(scene, overrides, camera)
    source = str(scene.path or ("default scene" if scene.name == "default" else scene.name))
    given_options = {k: v for k, v in kwargs.items() if k in OPTION_NAMES and v is not None}
    if "volumetric_shadows" not in given_options and "volumetric_shadows" not in scene.render:
        given_options["volumetric_shadows"] = True
    options = render_options(scene, source, **given_options)
    cam = scene.camera
    name = method or scene.render.get("method", AUTO)
    m = None if name == AUTO else get_method(name, source)
    explicit = {k: v for k, v in kwargs.items() if k not in OPTION_NAMES | IGNORED and v is not None}
    if options.progressive and (m is None or not m.stochastic):
        raise UserError(f"{source}: method {name} is deterministic; the progressive options passes, time_budget, "
                        "target_error and checkpoint (--passes, --time-budget, --target-error, --checkpoint) need "
                        "a stochastic method such as montecarlo")
    check_memory(cam, options.crop, m is not None and m.stochastic, source, options.max_memory)
    run_on = executor(options, client, source)
    prep = prepared if prepared is not None else renderer.prepare(scene)
    auto = None
    if m is None:
        m, given, auto = choose_method(prep, explicit, options, source)
    else:
        given = {**scene_defaults(table_params(scene), m, source), **explicit}
    if m.stochastic:
        from .rendering.progressive import render_progressive

        result = render_progressive(prep, m.name, given, options, run_on, source)
    else:
        result = renderer.render(prep, m.name, given, options, run_on, source)
    if np.any(np.isnan(result.image)):
        raise UserError(f"{source}: the render produced non-finite pixels; this is a bug, please report the scene")
    if not np.all(result.image < np.finfo(np.float32).max):
        over = int(np.sum(~(result.image < np.finfo(np.float32).max)))
        raise UserError(f"{source}: {counted(over, 'pixel channel exceeds', 'pixel channels exceed')} "
                        "float32's 3.4e38 (an EXR cannot hold them): lower the lights' intensity or the medium's "
                        "coefficients, or move the camera off the light it sits on")
    bound = result.error_bound
    if result.variance is not None:
        bound = error_bounds.with_standard_error(bound, result.variance)
    unbounded = float(np.isinf(bound).any(axis=-1).mean()) if bound is not None and bound.size else 0.0
    return Image(result.image, scene.name, result.method, result.params, result.stats, result.seconds,
                 result.compile_seconds, cam.spp, options.seed, options.crop, options.volumetric_shadows,
                 result.variance,
                 bound, auto, unbounded, unbounded_reason(prep, m, result) if unbounded else "", result.layers)


AUTO = "auto"  # the default method (SCENE_FORMAT.md): the first of AUTO_METHODS whose checks accept the scene
AUTO_METHODS = ("analytic", "quadrature")  # tried in this order; the last renders or refuses
ACCURACY = ("precision", "rtol")  # the keys of a requested relative accuracy: each of AUTO_METHODS reads one


def choose_method(prep, explicit: dict, options: RenderOptions, source: str):
    """method = "auto": the first of AUTO_METHODS (analytic) whose checks, those renderer.render
    makes before rendering (renderer.check), accept the scene, their UserError
    caught; else the last (quadrature). The requested accuracy (a key of ACCURACY, given explicitly or
    in [render]; default the first method's) goes to the picked method under its own key; every other
    parameter is the first method's, checked as such. Returns (method, parameters, the choice in
    words: "analytic" or "quadrature (analytic: why not)")."""
    from .methods import resolve_params
    from .rendering.renderer import check

    methods = [get_method(name, source) for name in AUTO_METHODS]
    key = {m.name: next(k for k in ACCURACY if k in m.params) for m in methods}  # each method's accuracy key
    table = table_params(prep.scene)
    value = methods[0].params[key[methods[0].name]].default
    for where, given in (("[render]", table), ("given", explicit)):  # explicit keywords win
        keys = [k for k in ACCURACY if k in given]
        if len(keys) > 1:
            raise UserError(f"{source}: {where} {' and '.join(keys)}: with method auto each names the accuracy (for "
                            f"{', '.join(f'{m.name} {key[m.name]}' for m in methods)}); give one")
        value = given[keys[0]] if keys else value
    others = {k: v for k, v in explicit.items() if k not in ACCURACY}
    defaults = {k: v for k, v in table.items() if k not in ACCURACY}
    refused = []
    for m in methods[:-1]:
        params = {**{k: v for k, v in defaults.items() if k in m.params}, **others, key[m.name]: value}
        resolve_params(m, params, source)  # a parameter it refuses is an error, not a reason to switch
        try:
            check(prep, m.name, params, options, source)
            picked = m
            break
        except UserError as exc:
            refused.append(f"{m.name}: {_refusal(exc, m, source)}")
    else:
        picked = methods[-1]
    choice = picked.name + (f" ({'; '.join(refused)})" if refused else "")
    return picked, {**scene_defaults(defaults, picked, source), **others, key[picked.name]: value}, choice


def _refusal(exc: UserError, method, source: str) -> str:
    """`method`'s refusal in a few words: its message without the source and the method's flag, up to
    the fix (what follows the first "; ")."""
    text = " ".join(str(exc).split())
    for prefix in (f"{source}: ", f"--method {method.name}: ", "it "):
        text = text.removeprefix(prefix)
    return text.split("; ")[0]


def unbounded_reason(prep, method, result) -> str:
    """Why pixels of a render have no finite error bound, in a few words, from what the render knows
    (docs/error_bounds.md lists the sources): the method's air-light gives no bound in this medium
    (asked of it: its airlight's third value on an empty batch), media inside shapes, the particle
    layer's glints, area lights (their emitter points are a cubature without a bound) and environment light (its
    directions are sampled). "" where none of
    these applies."""
    from .methods import Segments

    medium, why = prep.scene.medium, []
    if not method.stochastic:
        none = np.zeros((0, 3))
        empty = Segments(none, none, np.zeros(0), *(np.zeros(0, dtype=np.int64),) * 2, np.zeros(0),
                         np.zeros(0, dtype=np.uint64), np.zeros(0, dtype=np.int64))
        if len(method.airlight(empty, medium, prep.lights, result.params)) < 3:
            why.append(f"{method.name} gives no bound in {medium.type_name} media")
    if prep.interior_shapes is not None and len(prep.interior_shapes):
        handed = result.stats.get("inside: segments handed to quadrature", 0)
        why.append(f"media inside shapes ({counted(handed, 'segment')} handed to quadrature)" if handed else
                   "media inside shapes")
    if medium.particles is not None:
        why.append("particle glints")
    if prep.lights.cubature.any():
        why += prep.lights.unbounded()
    return ", ".join(why)
