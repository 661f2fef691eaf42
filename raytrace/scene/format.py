"""Scene files: TOML → validated dataclasses (SCENE_FORMAT.md).

Validation is strict: unknown keys are errors with a "did you mean", every number is checked for
type, sign and finiteness, and every message names the file, the key and the fix.
"""
from __future__ import annotations

import difflib
import math
import re
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import UserError, counted
from ..geometry.vectors import rotation_matrix
from ..lights import Light, check_at_infinity, emitter_shape, parse_light, power, sphere, two_sided
from ..media import Medium, parse_medium
from ..media.phase import HG, ISOTROPIC, RAYLEIGH
from .assets import find_asset

PRIMITIVES = ("box", "quad", "sphere", "cylinder", "triangles")


@dataclass
class Camera:
    type: str
    position: np.ndarray
    look_at: np.ndarray
    up: np.ndarray
    fov: float
    width: int
    height: int
    spp: int


@dataclass
class Transform:
    scale: np.ndarray
    rotate: np.ndarray  # degrees about x, then y, then z
    translate: np.ndarray


def apply_transform(points, t: Transform):
    """Scale, then rotate about x, y, z (degrees), then translate."""
    m = rotation_matrix(t.rotate) * t.scale[None, :]
    return points @ m.T + t.translate


def world_sphere(shape: Shape) -> tuple[np.ndarray, float] | None:
    """A sphere primitive's centre and radius in world space, or None where its transform scales it
    unevenly (an ellipsoid)."""
    t = shape.transform
    if np.ptp(np.abs(t.scale)) > 0.0:
        return None
    return apply_transform(shape.params["center"][None, :], t)[0], shape.params["radius"] * abs(float(t.scale[0]))


@dataclass
class Interior:
    """The homogeneous medium a closed shape holds (seed 002): coefficients per channel, phase function,
    and the index of refraction relative to the outside (1: index-matched, no boundary)."""
    sigma_a: np.ndarray
    sigma_s: np.ndarray
    phase: int = ISOTROPIC
    g: float = 0.0
    ior: float = 1.0

    @property
    def sigma_t(self) -> np.ndarray:
        return self.sigma_a + self.sigma_s


@dataclass
class Shape:
    kind: str  # "mesh" or one of PRIMITIVES
    params: dict  # mesh: {"mesh": path}; primitives: their numeric parameters
    reflectance: np.ndarray | None
    transform: Transform
    interior: Interior | None = None
    smooth: bool = True  # interpolated shading normals (scene/meshes.py); False: flat facets
    # radiance (W / (m^2 sr)) a camera ray sees on the front of its triangles (their winding's side; both
    # sides if two_sided): an area light's emitter (`light`: its index in Scene.lights; added by the reader)
    emission: np.ndarray | None = None
    two_sided: bool = False
    light: int | None = None


@dataclass
class Scene:
    name: str
    path: Path | None  # the scene file (None for the built-in default scene)
    camera: Camera
    shapes: list[Shape]
    lights: list[Light]
    medium: Medium
    background: np.ndarray
    render: dict = field(default_factory=dict)


class _Ctx:
    """Where we are in the file, to build messages that name the file and the key."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, key: str, problem: str, fix: str):
        raise UserError(f"{self.source}: {key}: {problem}; {fix}")

    def unknown(self, table: str, keys, allowed):
        for k in keys:
            if k not in allowed:
                close = difflib.get_close_matches(k, list(allowed), n=1, cutoff=0.6)
                hint = f'did you mean "{close[0]}"?' if close else "allowed keys: " + ", ".join(sorted(allowed))
                where = f"{table}.{k}" if table else k
                self.fail(where, "unknown key", hint)


def _number(ctx, key, value, *, minimum=None, positive=False, integer=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        ctx.fail(key, f"expected a number, got {value!r}", "write a number such as 1.0")
    if integer and not isinstance(value, int):
        ctx.fail(key, f"expected an integer, got {value!r}", "write a whole number such as 64")
    if not math.isfinite(value):
        ctx.fail(key, f"{value!r} is not finite", "use a finite number")
    if positive and value <= 0:
        ctx.fail(key, f"must be positive, got {value!r}", "use a value greater than 0")
    if minimum is not None and value < minimum:
        ctx.fail(key, f"must be >= {minimum}, got {value!r}", f"use a value of at least {minimum}")
    return value


def _vec3(ctx, key, value):
    if not isinstance(value, list) or len(value) != 3:
        ctx.fail(key, f"expected a vector [x, y, z], got {value!r}", "write three numbers in brackets")
    return np.array([_number(ctx, f"{key}[{i}]", v) for i, v in enumerate(value)], dtype=np.float64)


def _array(ctx, key, value, *, integer=False):
    """An (N, 3) array of finite numbers (vertices) or of non-negative integers (faces)."""
    what = "[i, j, k] vertex indices" if integer else "[x, y, z] points"
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        a = np.zeros((0, 0))
    if a.ndim != 2 or a.shape[1] != 3 or not np.all(np.isfinite(a)) or (integer and (np.any(a < 0) or np.any(a % 1))):
        ctx.fail(key, f"expected a list of {what}", f"write {key.rsplit('.', 1)[-1]} = [[..], [..], ...]")
    return a.astype(np.int64) if integer else a


def _rgb(ctx, key, value, *, minimum=0.0):
    """A colour or per-channel coefficient: [r, g, b] or one number for all three."""
    if isinstance(value, list):
        if len(value) != 3:
            ctx.fail(key, f"expected [r, g, b] or one number, got {value!r}", "give three numbers or one")
        return np.array([_number(ctx, f"{key}[{i}]", v, minimum=minimum) for i, v in enumerate(value)])
    v = _number(ctx, key, value, minimum=minimum)
    return np.full(3, float(v))


def _string(ctx, key, value, choices):
    if not isinstance(value, str) or value not in choices:
        close = difflib.get_close_matches(str(value), list(choices), n=1, cutoff=0.5)
        hint = f'did you mean "{close[0]}"?' if close else "choose one of: " + ", ".join(choices)
        ctx.fail(key, f"{value!r} is not one of {', '.join(choices)}", hint)
    return value


def _table(ctx, key, value):
    if not isinstance(value, dict):
        ctx.fail(key, f"expected a table, got {value!r}", f"write [{key}] with its keys")
    return value


CAMERA_KEYS = {"type", "position", "look_at", "up", "fov", "width", "height", "spp"}


def _camera(ctx, raw):
    raw = _table(ctx, "camera", raw)
    ctx.unknown("camera", raw, CAMERA_KEYS)
    kind = _string(ctx, "camera.type", raw.get("type", "perspective"), CAMERA_TYPES)
    for k in ("position", "look_at"):
        if k not in raw:
            ctx.fail(f"camera.{k}", "missing", f"add camera.{k} = [x, y, z]")
    pos = _vec3(ctx, "camera.position", raw["position"])
    look = _vec3(ctx, "camera.look_at", raw["look_at"])
    up = _vec3(ctx, "camera.up", raw.get("up", [0.0, 1.0, 0.0]))
    fwd = look - pos
    if np.linalg.norm(fwd) <= 1e-12 * max(1.0, np.linalg.norm(pos)):
        ctx.fail("camera.look_at", "equals camera.position", "look at a point away from the camera")
    if np.linalg.norm(up) == 0.0 or np.linalg.norm(np.cross(fwd / np.linalg.norm(fwd), up / np.linalg.norm(up))) < 1e-9:
        ctx.fail("camera.up", "is zero or parallel to the view direction", "choose an up vector not along look_at - position")
    fov = _number(ctx, "camera.fov", raw.get("fov", 60.0), positive=True)
    if fov >= 180.0:
        ctx.fail("camera.fov", f"must be below 180 degrees, got {fov!r}", "use a vertical field of view such as 60")
    width = _number(ctx, "camera.width", raw.get("width", 512), positive=True, integer=True)
    height = _number(ctx, "camera.height", raw.get("height", 512), positive=True, integer=True)
    spp = _number(ctx, "camera.spp", raw.get("spp", 1), positive=True, integer=True)
    return Camera(kind, pos, look, up, float(fov), width, height, spp)


CAMERA_TYPES = ("perspective", "environment")  # camera.type: a pinhole, or equirectangular 360 x 180
TRANSFORM_KEYS = {"scale", "rotate", "translate"}
PRIMITIVE_KEYS = {
    "box": {"min", "max"},
    "quad": {"corners"},
    "sphere": {"center", "radius", "segments", "exact"},  # exact: intersected as a sphere (geometry/sphere.py)
    "cylinder": {"base", "top", "radius", "segments"},
    "triangles": {"vertices", "faces", "normals"},  # an inline mesh (what the glTF, Mitsuba and pbrt importers write)
}
SHAPE_COMMON = {"mesh", "primitive", "reflectance", "transform", "interior", "smooth", "emission", "two_sided"}
INTERIOR_KEYS = {"sigma_a", "sigma_s", "phase", "ior"}
MAX_SEGMENTS = 2048  # a sphere of 2048 segments: 4.2 million triangles, ~0.3 GB (segments = 1e9 hung)


def _transform(ctx, key, raw):
    if raw is None:
        return Transform(np.ones(3), np.zeros(3), np.zeros(3))
    raw = _table(ctx, key, raw)
    ctx.unknown(key, raw, TRANSFORM_KEYS)
    scale = raw.get("scale", 1.0)
    scale = _vec3(ctx, f"{key}.scale", scale) if isinstance(scale, list) else np.full(3, float(_number(ctx, f"{key}.scale", scale)))
    if np.any(scale == 0.0):
        ctx.fail(f"{key}.scale", "contains 0, which flattens the shape", "use a non-zero scale")
    return Transform(scale, _vec3(ctx, f"{key}.rotate", raw.get("rotate", [0.0, 0.0, 0.0])),
                     _vec3(ctx, f"{key}.translate", raw.get("translate", [0.0, 0.0, 0.0])))


def _shape(ctx, i, raw):
    key = f"shape[{i}]"
    raw = _table(ctx, key, raw)
    if ("mesh" in raw) == ("primitive" in raw):
        ctx.fail(key, "needs exactly one of mesh or primitive", 'write mesh = "file.obj" or primitive = "box"')
    if "mesh" in raw:
        ctx.unknown(key, raw, SHAPE_COMMON)
        if not isinstance(raw["mesh"], str) or not raw["mesh"]:
            ctx.fail(f"{key}.mesh", f"expected a file name, got {raw['mesh']!r}", 'write mesh = "folder/model.obj"')
        kind, params = "mesh", {"mesh": raw["mesh"]}
    else:
        kind = _string(ctx, f"{key}.primitive", raw["primitive"], PRIMITIVES)
        ctx.unknown(key, raw, SHAPE_COMMON | PRIMITIVE_KEYS[kind])
        params = {}
        for k in sorted(PRIMITIVE_KEYS[kind]):
            if k == "segments":
                params[k] = _number(ctx, f"{key}.segments", raw.get(k, 32), integer=True, minimum=3)
                if params[k] > MAX_SEGMENTS:
                    ctx.fail(f"{key}.segments", f"must be at most {MAX_SEGMENTS} (a sphere of n segments has about n^2 "
                             f"triangles), got {params[k]!r}", "use fewer segments")
            elif k == "exact":
                params[k] = raw.get(k, False)
                if not isinstance(params[k], bool):
                    ctx.fail(f"{key}.exact", f"expected true or false, got {params[k]!r}",
                             "write exact = true for a sphere intersected exactly")
            elif k == "radius":
                if k not in raw:
                    ctx.fail(f"{key}.radius", "missing", f"add {key}.radius = 1.0")
                params[k] = float(_number(ctx, f"{key}.radius", raw[k], positive=True))
            elif k in ("vertices", "faces"):
                params[k] = _array(ctx, f"{key}.{k}", raw.get(k), integer=k == "faces")
            elif k == "normals":  # optional: a shading normal per vertex (smooth shading)
                if k in raw:
                    params[k] = _array(ctx, f"{key}.normals", raw[k])
            elif k == "corners":
                c = raw.get(k)
                if not isinstance(c, list) or len(c) != 4:
                    ctx.fail(f"{key}.corners", "expected four [x, y, z] corners in order around the quad",
                             "write corners = [[..], [..], [..], [..]]")
                params[k] = np.array([_vec3(ctx, f"{key}.corners[{j}]", p) for j, p in enumerate(c)])
            else:
                if k not in raw:
                    ctx.fail(f"{key}.{k}", "missing", f"add {key}.{k} = [x, y, z]")
                params[k] = _vec3(ctx, f"{key}.{k}", raw[k])
        if kind == "triangles" and "normals" in params and len(params["normals"]) != len(params["vertices"]):
            ctx.fail(f"{key}.normals", f"needs one normal per vertex ({len(params['vertices'])}), got "
                     f"{len(params['normals'])}", "give as many normals as vertices, or remove normals")
        if kind == "triangles" and (params["faces"].size == 0 or params["faces"].max() >= len(params["vertices"])):
            ctx.fail(f"{key}.faces", f"index vertices 0..{len(params['vertices']) - 1} and hold at least one triangle",
                     "write faces = [[0, 1, 2], ...] with indices into vertices")
        if kind == "box" and np.any(params["max"] <= params["min"]):
            ctx.fail(f"{key}.max", "must exceed min in every coordinate", "swap or fix min and max")
    refl = raw.get("reflectance")
    if refl is not None and "interior" in raw:
        ctx.fail(f"{key}.reflectance", "is not read on a shape that holds a medium (light crosses its boundary, a "
                 "smooth dielectric or index-matched)", "remove reflectance, or the interior for an opaque surface")
    refl = None if refl is None else _rgb(ctx, f"{key}.reflectance", refl)
    if refl is not None and np.any(refl > 1.0):
        ctx.fail(f"{key}.reflectance", "exceeds 1 (surfaces would create energy)", "use values in [0, 1]")
    interior = _interior(ctx, f"{key}.interior", raw["interior"]) if "interior" in raw else None
    smooth = raw.get("smooth", True)
    if not isinstance(smooth, bool):
        ctx.fail(f"{key}.smooth", f"expected true or false, got {smooth!r}", "write smooth = false for flat facets")
    emission, two_sided = _emission(ctx, key, raw)
    transform = _transform(ctx, f"{key}.transform", raw.get("transform"))
    if kind == "sphere" and params["exact"]:
        _exact_sphere(ctx, key, raw, transform)
    return Shape(kind, params, refl, transform, interior, smooth, emission, two_sided)


def _exact_sphere(ctx, key, raw, transform):
    """Refuse what an exact sphere does not take: emission on both sides, a non-uniform scale."""
    if "emission" in raw and raw.get("two_sided", False) is True:
        ctx.fail(f"{key}.two_sided", "an exact sphere that emits is a sphere light, which emits outward only",
                 f"remove two_sided, or set {key}.exact = false (a mesh of `segments`)")
    if np.ptp(np.abs(transform.scale)) > 0.0:
        ctx.fail(f"{key}.transform.scale", "an exact sphere scaled unevenly is an ellipsoid, which is not read",
                 f"scale it uniformly, or set {key}.exact = false")


def _emission(ctx, key, raw):
    """(emission, two_sided) of a shape: the radiance its triangles emit (lights/emissive.py), or None."""
    if "emission" not in raw:
        if "two_sided" in raw:
            ctx.fail(f"{key}.two_sided", "is read only with emission", "remove it, or add emission = [r, g, b]")
        return None, False
    if "interior" in raw:
        ctx.fail(f"{key}.emission", "a shape that holds a medium cannot emit yet", "remove emission or the interior")
    read = _Reader(ctx)
    return power(read, f"{key}.emission", _rgb(ctx, f"{key}.emission", raw["emission"])), two_sided(read, key, raw)


def _emitting_spheres(shapes: list[Shape], lights: list[Light]):
    """Each exact sphere that emits becomes a sphere light (lights/sphere.py), appended to `lights`,
    whose emitter is that shape (its `light`): drawn exactly, with the sphere light's rule along rays."""
    for i, shape in enumerate(shapes):
        if shape.kind == "sphere" and shape.params["exact"] and shape.emission is not None and shape.light is None:
            lights.append(sphere.of_shape(*world_sphere(shape), shape.emission))
            shapes[i] = replace(shape, light=len(lights) - 1)


def _emitters(lights) -> list[Shape]:
    """The area lights' emitters as black shapes of their radiance (lights.emitter_shape): seen by the
    camera, occluding like shapes; after the file's own shapes."""
    out = []
    for i, light in enumerate(lights):
        made = emitter_shape(light)
        if made is not None:
            out.append(Shape(made[0], made[1], np.zeros(3), Transform(np.ones(3), np.zeros(3), np.zeros(3)),
                             smooth=False, emission=light.intensity, two_sided=light.two_sided, light=i))
    return out


def _interior(ctx, key, raw):
    """shape.interior = { sigma_a, sigma_s, phase, ior }: a homogeneous medium inside a closed shape."""
    raw = _table(ctx, key, raw)
    ctx.unknown(key, raw, INTERIOR_KEYS)
    ior = _number(ctx, f"{key}.ior", raw.get("ior", 1.0))
    if ior <= 0.0:
        ctx.fail(f"{key}.ior", f"must be positive, got {ior!r}", "use the index of refraction relative to the outside, "
                 "e.g. 1.33 for water (1 = index-matched)")
    sa = _rgb(ctx, f"{key}.sigma_a", raw.get("sigma_a", 0.0))
    ss = _rgb(ctx, f"{key}.sigma_s", raw.get("sigma_s", 0.0))
    return Interior(sa, ss, *_phase(ctx, raw.get("phase", "isotropic"), f"{key}.phase"), float(ior))


class _Reader:
    """The parsing helpers bound to the file, for the media and light kinds' own parsers (media/medium.py)."""

    def __init__(self, ctx, path: Path | None = None):
        self.fail, self.unknown = ctx.fail, ctx.unknown
        self.ctx, self.path = ctx, path

    def image(self, key, name, what):
        """(the (H, W, 3) float64 RGB of the EXR file `name`, its path): a `what` (e.g. "environment map")
        found as meshes are (scene/assets.py)."""
        from ..output.film import read_exr

        path = find_asset(name, self.path, key, what)
        try:
            return read_exr(path)[0], path
        except UserError:
            self.fail(key, f"{path} is not a readable RGB OpenEXR image", "give a linear RGB .exr file")

    def number(self, key, value, **kw):
        return _number(self.ctx, key, value, **kw)

    def vec3(self, key, value):
        return _vec3(self.ctx, key, value)

    def rgb(self, key, value):
        return _rgb(self.ctx, key, value)

    def string(self, key, value, choices):
        return _string(self.ctx, key, value, choices)

    def table(self, key, value):
        return _table(self.ctx, key, value)

    def phase(self, value, key):
        return _phase(self.ctx, value, key)


def _phase(ctx, phase, key="medium.phase"):
    """(phase.py code, g) of the phase function at `key` (medium.phase, an atmosphere layer's or a
    shape's interior.phase)."""
    if isinstance(phase, str):
        name = _string(ctx, key, phase, ("isotropic", "rayleigh", "hg"))
        if name == "hg":
            ctx.fail(key, "Henyey-Greenstein needs its asymmetry g", 'write phase = { type = "hg", g = 0.5 }')
        return (ISOTROPIC if name == "isotropic" else RAYLEIGH), 0.0
    phase = _table(ctx, key, phase)
    ctx.unknown(key, phase, {"type", "g"})
    name = _string(ctx, f"{key}.type", phase.get("type", "hg"), ("isotropic", "rayleigh", "hg"))
    if name != "hg":
        if "g" in phase:
            ctx.fail(f"{key}.g", f"only Henyey-Greenstein takes g, not {name}", 'remove g or use type = "hg"')
        return (ISOTROPIC if name == "isotropic" else RAYLEIGH), 0.0
    if "g" not in phase:
        ctx.fail(f"{key}.g", "missing", "add g in (-1, 1), e.g. g = 0.5")
    g = float(_number(ctx, f"{key}.g", phase["g"]))
    if not abs(g) < 1.0:
        ctx.fail(f"{key}.g", f"|g| must be below 1, got {g!r}", "use -1 < g < 1 (g > 0 scatters forward)")
    return HG, g


RENDER_OPTIONS = ("method", "seed", "volumetric_shadows", "shadow_spacing", "aov")  # [render] keys that are not method parameters


def render_keys():
    """Keys allowed in [render]: the render options and every parameter some registered method
    declares (checked against the chosen method when rendering)."""
    from ..methods import registry

    keys = set(RENDER_OPTIONS)
    for m in registry().values():
        keys |= set(m.params)
    return keys


def _render(ctx, raw):
    if raw is None:
        return {}
    raw = _table(ctx, "render", raw)
    ctx.unknown("render", raw, render_keys())
    out = dict(raw)
    if "method" in out:
        from ..methods import registry

        _string(ctx, "render.method", out["method"], ("auto", *registry()))  # auto: api.choose_method
    if "seed" in out:
        _number(ctx, "render.seed", out["seed"], integer=True, minimum=0)
    if "volumetric_shadows" in out and not isinstance(out["volumetric_shadows"], bool):
        ctx.fail("render.volumetric_shadows", f"expected true or false, got {out['volumetric_shadows']!r}",
                 "write volumetric_shadows = true")
    if "shadow_spacing" in out:
        _number(ctx, "render.shadow_spacing", out["shadow_spacing"], positive=True)
    return out


TOP_KEYS = {"name", "camera", "shape", "light", "medium", "background", "render"}


def scene_from_dict(raw: dict, source: str, path: Path | None = None) -> Scene:
    """Validate a parsed TOML document; `source` names it in error messages."""
    ctx = _Ctx(source)
    ctx.unknown("", raw, TOP_KEYS)
    if "camera" not in raw:
        ctx.fail("camera", "missing", "add a [camera] table with position and look_at")
    camera = _camera(ctx, raw["camera"])
    shapes_raw = raw.get("shape", [])
    if not isinstance(shapes_raw, list):
        ctx.fail("shape", "expected an array of tables", "write each shape as [[shape]]")
    lights_raw = raw.get("light", [])
    if not isinstance(lights_raw, list):
        ctx.fail("light", "expected an array of tables", "write each light as [[light]]")
    background = raw.get("background", {})
    background = _table(ctx, "background", background)
    ctx.unknown("background", background, {"radiance"})
    name = raw.get("name", path.stem if path else "scene")
    if not isinstance(name, str):
        ctx.fail("name", f"expected a string, got {name!r}", 'write name = "my scene"')
    shapes = [_shape(ctx, i, s) for i, s in enumerate(shapes_raw)]
    read = _Reader(ctx, path)
    lights = [parse_light(read, i, s) for i, s in enumerate(lights_raw)]
    check_at_infinity(read, lights, "background" in raw)
    shapes += _emitters(lights)
    _emitting_spheres(shapes, lights)
    medium = parse_medium(read, raw.get("medium"))
    medium.check_scene(read, camera, lights)
    return Scene(
        name=name,
        path=path,
        camera=camera,
        shapes=shapes,
        lights=lights,
        medium=medium,
        background=_rgb(ctx, "background.radiance", background.get("radiance", 0.0)),
        render=_render(ctx, raw.get("render")),
    )


def parse_override(text: str, source: str):
    """Split a ``--set key.path=value`` override into the canonical key (entries of arrays in
    brackets: ``light[1].intensity``, as error messages write them; ``light.1.intensity`` is read the
    same) and the value, read as TOML, or as a bare string."""
    if "=" not in text:
        raise UserError(f"{source}: --set {text}: expected key.path=value; for example --set medium.sigma_s=0.2")
    key, value = text.split("=", 1)
    key = override_key(_key_parts(key.strip(), text, source))
    try:
        parsed = tomllib.loads(f"v = {value}")["v"]
    except tomllib.TOMLDecodeError as exc:
        parsed = value.strip()
        if parsed[:1] in _TOML_OPENERS:  # an array, table or string that is not well formed: not a bare word
            reason = re.sub(r" \(at .*\)$", "", str(exc))
            raise UserError(f"{source}: --set {key}={parsed}: bad TOML ({reason}); write a complete TOML "
                            f"{_TOML_OPENERS[parsed[0]][0]}, quoted for the shell, e.g. "
                            f"--set '{key}={_TOML_OPENERS[parsed[0]][1]}'") from None
    return key, parsed


# what a --set value that opens with these characters must be, with an example
_TOML_OPENERS = {"[": ("array", "[1, 2, 3]"), "{": ("inline table", '{type = "hg", g = 0.5}'),
                 '"': ("string", '"text"'), "'": ("string", "'text'")}


_SEGMENT = re.compile(r"([^.\[\]\s]+)((?:\[[0-9]+\])*)")


def _key_parts(key: str, text: str, source: str) -> list:
    """``a.b[1].c`` or ``a.b.1.c`` as ["a", "b", 1, "c"]: names, and integers that index arrays."""
    parts = []
    for segment in key.split("."):
        m = _SEGMENT.fullmatch(segment)
        if not m:
            raise UserError(f"{source}: --set {text}: malformed key {key!r}; write names joined by dots and array "
                            "entries in brackets, for example --set medium.sigma_s=0.2 or --set light[1].intensity=20")
        name, index = m.groups()
        parts.append(int(name) if name.isdigit() else name)
        parts += [int(i) for i in re.findall(r"[0-9]+", index)]
    return parts


def override_key(parts) -> str:
    """The canonical spelling of a key path: ``light[1].position[0]``."""
    return "".join(f"[{p}]" if isinstance(p, int) else (f".{p}" if i else p) for i, p in enumerate(parts))


def apply_override(raw: dict, key: str, value, source: str):
    """Set raw[a][b]... = value for key "a.b..." (either spelling); integers index arrays
    (light[1].intensity, camera.position[0])."""
    parts = _key_parts(key, key, source)
    key = override_key(parts)
    node = raw
    for i, part in enumerate(parts):
        where, last = override_key(parts[:i]), i == len(parts) - 1
        if isinstance(node, list):
            if not isinstance(part, int) or part >= len(node):
                raise UserError(f"{source}: --set {key}: {where} has {counted(len(node), 'entry', 'entries')}; "
                                + (f"index it as {where}[0]" if len(node) == 1 else
                                   f"index them 0..{len(node) - 1}, e.g. {where}[0]") if node else
                                f"{source}: --set {key}: {where} is empty; set it as a whole")
        elif isinstance(part, int):
            raise UserError(f"{source}: --set {key}: {where or 'the scene'} is a table, not an array; name its key")
        elif part in ("shape", "light") and part not in node and not last:
            raise UserError(f"{source}: --set {key}: the scene has no [[{part}]]; add one to the file")
        if last:
            node[part] = value
            return
        if isinstance(node, dict):
            node = node.setdefault(part, {})
        else:
            node = node[part]
        if not isinstance(node, (dict, list)):
            raise UserError(f"{source}: --set {key}: {override_key(parts[:i + 1])} is not a table; set it as a whole")


def read_toml(path: Path) -> dict:
    """The scene dict of a TOML scene file. Raises UserError naming the file and the fix."""
    source = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{source}: no such scene file; check the path") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{source}: cannot read the scene file ({exc}); check its permissions and encoding") from None
    return _parse_toml(text, source)


def _parse_toml(text: str, source: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{source}: malformed TOML ({exc}); fix the syntax at that line") from None


def load_scene(path: str | Path, overrides=()) -> Scene:
    """Read, override and validate a TOML scene file. Raises UserError naming the file, key and fix."""
    path = Path(path)
    raw = read_toml(path)
    for item in overrides:
        apply_override(raw, *parse_override(item, str(path)), str(path))
    return scene_from_dict(raw, str(path), path)


def scene_from_text(text: str, source: str, path: Path | None = None, overrides=()) -> Scene:
    raw = _parse_toml(text, source)
    for item in overrides:
        apply_override(raw, *parse_override(item, source), source)
    return scene_from_dict(raw, source, path)
