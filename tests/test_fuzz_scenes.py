"""A scene fuzzer (issue 15): random scenes across the whole format, valid and near-valid.

`scene()` draws every primitive (box, quad, sphere, cylinder) with and without transforms, point,
spot and directional lights (anywhere: inside, on walls, outside, on the camera), homogeneous media
(with and without `[medium.particles]`) and height fogs (exponential and linear), every phase, both
cameras, magnitudes from 0 to 1e300, shapes holding a medium (`interior`, index-matched or refractive, on
any primitive or a closed non-convex U mesh; the camera inside one; vacuum outside; an open U or a
flat shape with an interior, which must be refused); `planet_scene()` a planet's atmosphere (100 m
to Earth-sized, 1-3 layers, cameras and lamps on the ground, in the air, in space, grazing the ground
or the top); `render_args()` every registered method with random values of
its own parameters (volumetric shadows, shadow_test, sampling modes). `near_valid()` then spoils one
thing: a misspelt key (interior and layer keys too), a number out of range, degenerate geometry. Each scene either renders an
image of finite, non-negative pixels (and variances; lecocq and analytic --anisotropic taylor, the
papers' raw series: finite), or is refused with one line (UserError) that
is not "this is a bug" and, for a spoiled scene, names the spoiled key; never another exception, never
a numpy floating-point warning.

`lit_scene()` aims at what most fuzzed scenes are not: lit, moderately thick box rooms (sigma_t h
from 0.01 to 10 across the room, lights inside, an occluder, volumetric shadows on or off), on which
every deterministic method must agree with `quadrature` within its own declared error law
(`Method.error_law`, raytrace/methods/__init__.py, as tests/test_methods.py applies it); sometimes
the occluding sphere holds an index-matched medium. `lit_planet()`: small sunlit atmospheres, where
raymarch is held to its order (the other deterministic methods refuse atmospheres).

Fixed seed (derandomized); the suite runs a few dozen scenes, `pytest -m slow -k fuzz` runs 1000
of each fuzzer (atmospheres too) and prints the counts of scenes rendered and refused.
"""
from __future__ import annotations

import collections
import copy
import math
import os
import tempfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

import raytrace
from raytrace.errors import UserError
from raytrace.methods import registry

from .conftest import box_room
from .test_inside_paths import u_obj

MESHES = tempfile.mkdtemp(prefix="fuzz-meshes-")  # a closed non-convex U and the same U with one face removed
CLOSED_U, OPEN_U = os.path.join(MESHES, "u.obj"), os.path.join(MESHES, "u_open.obj")
with open(CLOSED_U, "w") as _f:
    _f.write(u_obj())
with open(OPEN_U, "w") as _f:
    _f.write("\n".join(u_obj().splitlines()[:-1]) + "\n")

METHODS_BY_NAME = registry()
MAGNITUDES = st.sampled_from([0.0, 1e-300, 1e-30, 1e-6, 0.01, 0.1, 1.0, 10.0, 1e6, 1e30, 1e150, 1e300])
POSITIVE = st.sampled_from([1e-300, 1e-30, 1e-6, 0.01, 0.1, 1.0, 10.0, 1e6, 1e30, 1e300])
# mostly inside the room ([-3, 3] x [-2, 2] x [-4, 4]), sometimes on or beyond its walls
coord = st.one_of(st.floats(-1.875, 1.875, width=32), st.floats(-5.0, 5.0, width=32), st.sampled_from([-3.0, 2.0, 4.0]))
vec = st.tuples(coord, coord, coord).map(list)
# half the time a moderate value, so that a good share of the scenes is lit
MAGNITUDE = st.one_of(st.floats(0.0, 2.0), MAGNITUDES)
rgb = st.one_of(MAGNITUDE, st.tuples(MAGNITUDE, MAGNITUDE, MAGNITUDE).map(list))
unit = st.floats(0.0, 1.0)
colour = st.one_of(unit, st.tuples(unit, unit, unit).map(list))
phase = st.one_of(st.sampled_from(["isotropic", "rayleigh", {"type": "rayleigh"}, {"type": "isotropic"}]),
                  st.floats(-0.999, 0.999, allow_nan=False).map(lambda g: {"type": "hg", "g": g}))


@st.composite
def transform(draw):
    out = {}
    if draw(st.booleans()):
        out["scale"] = draw(st.one_of(st.sampled_from([1e-30, 0.5, -1.0, 2.0, 1e30]),
                                      st.tuples(*[st.sampled_from([-2.0, 0.5, 1.0, 3.0])] * 3).map(list)))
    if draw(st.booleans()):
        out["rotate"] = draw(st.tuples(*[st.floats(-360.0, 360.0)] * 3).map(list))
    if draw(st.booleans()):
        out["translate"] = draw(vec)
    return out


@st.composite
def interior(draw):
    """A shape's medium (seed 002): index-matched or refractive, thin to opaque."""
    out = {}
    for k, s in (("sigma_a", rgb), ("sigma_s", rgb), ("phase", phase),
                 ("ior", st.sampled_from([1.0, 1.0, 1.0, 1.33, 2.4, 0.5, 1e-30, 1e30]))):
        if draw(st.integers(0, 3)) > 0:
            out[k] = draw(s)
    return out


@st.composite
def shape(draw, mesh=True):
    kind = draw(st.sampled_from(["box", "quad", "sphere", "cylinder"] + (["mesh"] if mesh else [])))
    out = {"primitive": kind}
    if kind == "mesh":  # the U (non-convex), sometimes open (refused with an interior)
        out = {"mesh": draw(st.sampled_from([CLOSED_U, CLOSED_U, OPEN_U]))}
    elif kind == "box":
        lo = draw(vec)
        out.update(min=lo, max=[a + draw(st.sampled_from([1e-6, 0.1, 1.0, 4.0])) for a in lo])
    elif kind == "quad":
        a, b, c = draw(vec), draw(vec), draw(vec)
        out["corners"] = [a, b, c, [a[i] + c[i] - b[i] for i in range(3)]]  # a parallelogram (or a line)
    else:
        out["radius"] = draw(st.sampled_from([1e-6, 0.1, 0.5, 1.5, 10.0]))
        out["segments"] = draw(st.sampled_from([3, 4, 7, 12]))
        if kind == "sphere":
            out["center"] = draw(vec)
        else:
            out["base"], out["top"] = draw(vec), draw(vec)
    if draw(st.booleans()):
        out["reflectance"] = draw(colour)
    if draw(st.integers(0, 3)) == 0:
        out["transform"] = draw(transform())
    if kind != "quad" and out.get("mesh") != OPEN_U and draw(st.integers(0, 2)) == 0:  # (open ones: near_valid)
        out["interior"] = draw(interior())
    return out


def centre(sh) -> list:
    """A point inside shape `sh` before its transform (a camera inside it)."""
    if "min" in sh:
        return [(a + b) / 2.0 for a, b in zip(sh["min"], sh["max"])]
    if "center" in sh:
        return list(sh["center"])
    if "base" in sh:
        return [(a + b) / 2.0 for a, b in zip(sh["base"], sh["top"])]
    if "mesh" in sh:
        return [-0.7, 0.0, 0.0]  # in the U's left arm
    return [sum(c[i] for c in sh["corners"]) / 4.0 for i in range(3)]


@st.composite
def light(draw, kinds=("point", "spot", "directional")):
    kind = draw(st.sampled_from(kinds))
    if kind == "directional":
        return {"type": "directional", "direction": draw(vec), "irradiance": draw(rgb)}
    out = {"position": draw(vec), "intensity": draw(rgb)}
    if kind == "spot":
        cone = draw(st.one_of(st.sampled_from([1e-3, 0.5, 1.0, 30.0, 90.0, 179.0, 179.999]), st.floats(1e-3, 179.999)))
        axis = "direction" if draw(st.booleans()) else "look_at"
        out.update(type="spot", cone_angle=cone, falloff_start=draw(unit) * cone, **{axis: draw(vec)})
    elif draw(st.booleans()):
        out["type"] = "point"
    return out


@st.composite
def particles(draw):
    out = {}
    for k, s in (("density", unit), ("mu", st.floats(-2.0, 2.0)), ("sigma", st.sampled_from([1e-3, 0.2, 1.0])),
                 ("cell", st.sampled_from([0.3, 1.0, 3.0])), ("offset", st.sampled_from([0.0, 0.5])),
                 ("reflectance", unit), ("seed", st.integers(0, 2**63 - 1))):
        if draw(st.booleans()):
            out[k] = draw(s)
    if draw(st.booleans()):
        out["beta"] = draw(st.sampled_from([1e-3, 0.05, 1.0]))
    elif draw(st.booleans()):
        out["c1"], out["c2"] = draw(st.sampled_from([0.0, 0.05])), draw(st.sampled_from([0.0, 0.03, 1.0]))
    return out


@st.composite
def medium(draw):
    out = {"sigma_a": draw(rgb), "sigma_s": draw(rgb), "phase": draw(phase)}
    if draw(st.booleans()):
        out["type"] = "height_fog"
        out["scale_height"] = draw(st.one_of(st.floats(0.1, 10.0), POSITIVE))
        for k, s in (("up", vec.filter(lambda v: any(v))), ("h0", coord),
                     ("profile", st.sampled_from(["exponential", "linear"]))):
            if draw(st.booleans()):
                out[k] = draw(s)
    elif draw(st.integers(0, 3)) == 0 and np.any(np.asarray(out["sigma_s"]) > 0):
        out["particles"] = draw(particles())
    return out


@st.composite
def scene(draw):
    cam = {"type": draw(st.sampled_from(["perspective", "environment"])), "position": draw(vec),
           "look_at": draw(vec), "width": 4, "height": 3, "spp": draw(st.sampled_from([1, 1, 2]))}
    if draw(st.booleans()):
        cam["fov"] = draw(st.sampled_from([1e-3, 10.0, 70.0, 179.0]))
    if draw(st.integers(0, 3)) == 0:
        cam["up"] = draw(vec)
    lights = draw(st.lists(light(), min_size=0, max_size=3))
    point_like = [x for x in lights if x.get("type") != "directional"]
    if point_like and draw(st.booleans()):
        point_like[0]["position"] = list(cam["position"])  # a camera on a light
    room = draw(st.integers(0, 3)) > 0
    sc = box_room(camera=cam, light=lights, medium=draw(medium()))
    sc["shape"] = (sc["shape"] if room else []) + draw(st.lists(shape(), min_size=0 if room else 1, max_size=2))
    holders = [x for x in sc["shape"] if "interior" in x]
    if holders and draw(st.booleans()):
        cam["position"] = centre(draw(st.sampled_from(holders)))  # a camera inside a medium
    if holders and draw(st.booleans()):
        sc["medium"] = {"sigma_a": 0.0, "sigma_s": 0.0}  # vacuum outside
    if holders and draw(st.booleans()):  # lights the bounded media take: point lights (spots are refused)
        for x in point_like:
            for k in ("type", "cone_angle", "falloff_start", "direction", "look_at"):
                x.pop(k, None)
    if draw(st.integers(0, 3)) == 0:
        sc["background"] = {"radiance": draw(colour)}
    if not lights:
        del sc["light"]
    return sc


@st.composite
def planet_scene(draw):
    """A planet's atmosphere (medium.type = "atmosphere"): a 100 m, 1 km or Earth-sized planet with
    one to three exponential layers (optical depths per scale height from 0 to 1e3, and extreme ones),
    the camera on the ground, in the air, in space or grazing the planet or the top, lights there too
    (the sun anywhere, lamps above the ground or, refused, below it), sometimes a small shape."""
    radius = draw(st.sampled_from([100.0, 1000.0, 6360000.0]))
    top = radius * (1.0 + draw(st.sampled_from([1e-4, 0.01, 0.1, 1.0])))
    c = [0.0, -radius, 0.0]
    layers = []
    for i in range(draw(st.integers(1, 3))):
        h = radius * draw(st.sampled_from([1e-5, 1e-3, 0.01, 0.1, 1.0 / 3.0]))
        kt = draw(st.one_of(st.sampled_from([0.0, 1e-3, 0.1, 1.0, 10.0, 1e3]), MAGNITUDES.map(lambda m: m * h))) / h
        layer = {"sigma_s": draw(st.one_of(st.just(kt), st.tuples(*[st.sampled_from([0.0, 0.2, 1.0])] * 3).map(
            lambda f: [kt * x for x in f]))), "scale_height": h, "phase": draw(phase)}
        if draw(st.booleans()):
            layer["sigma_a"] = kt * draw(st.sampled_from([0.0, 0.1, 1.0]))
        if draw(st.booleans()):
            layer["name"] = f"layer {i}"
        layers.append(layer)
    med = {"type": "atmosphere", "center": c, "radius": radius, "top_radius": top, "layer": layers}
    if draw(st.booleans()):
        med["reflectance"] = draw(colour)

    def direction():
        v = draw(st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: sum(x * x for x in v) > 1e-4))
        return [x / math.sqrt(sum(y * y for y in v)) for x in v]

    def place():
        """A point on the ground, in the air, in space, below the ground (refused) or near the origin."""
        where = draw(st.sampled_from(["ground", "air", "space", "far", "origin", "under"]))
        if where == "origin":
            return [0.0, draw(st.sampled_from([0.0, 1e-6, 2.0])), 0.0]
        r = {"ground": radius * (1.0 + 1e-9), "air": (radius + top) / 2.0, "space": top * 1.01, "far": 3.0 * top,
             "under": radius * 0.99}[where]
        up = direction() if draw(st.booleans()) else [0.0, 1.0, 0.0]
        return [ci + r * u for ci, u in zip(c, up)]

    pos = place()
    how = draw(st.sampled_from(["random", "down", "grazing ground", "grazing top"]))
    d = [p - ci for p, ci in zip(pos, c)]
    r = math.sqrt(sum(x * x for x in d))
    if how == "random" or r <= radius:
        view = direction()
    elif how == "down":
        view = [-x for x in d]
    else:  # toward a point on the sphere's horizon seen from the camera, when outside the sphere
        s_r = radius if how == "grazing ground" else top
        if r <= s_r:
            view = [d[2], 0.0, -d[0]] if abs(d[0]) + abs(d[2]) > 0 else [1.0, 0.0, 0.0]
        else:
            side = [d[2], 0.0, -d[0]]  # perpendicular to d (x along d: any horizontal)
            n = math.sqrt(sum(x * x for x in side))
            if not n > 1e-6 * r:
                side, n = [1.0, 0.0, 0.0], 1.0
            tangent = math.sqrt(r * r - s_r * s_r)
            # tangent direction: -d/r * (tangent / r) + side/n * (s_r / r)
            view = [-x / r * tangent / r + y / n * s_r / r for x, y in zip(d, side)]
    scale = max(1.0, r) if r > 0 else 1.0
    cam = {"type": draw(st.sampled_from(["perspective", "environment"])), "position": pos,
           "look_at": [p + scale * v for p, v in zip(pos, view)], "width": 4, "height": 3, "spp": 1}
    if draw(st.booleans()):
        cam["fov"] = draw(st.sampled_from([1e-3, 10.0, 70.0, 179.0]))
    if abs(view[1]) > 0.99:  # looking straight down or up: the default up is along the view
        cam["up"] = [1.0, 0.0, 0.0]
    lights = []
    for _ in range(draw(st.integers(0, 2))):
        kind = draw(st.sampled_from(["directional", "directional", "point", "spot"]))
        power = draw(st.one_of(st.floats(0.0, 20.0), MAGNITUDES))
        if kind == "directional":
            lights.append({"type": "directional", "direction": direction(), "irradiance": power})
            continue
        x = {"type": kind, "position": pos if draw(st.integers(0, 5)) == 0 else place(), "intensity": power * radius ** 2 if power <= 20.0 else power}
        if kind == "spot":
            x.update(direction=direction(), cone_angle=draw(st.sampled_from([1.0, 30.0, 90.0, 179.0])))
        lights.append(x)
    sc = {"camera": cam, "medium": med}
    if lights:
        sc["light"] = lights
    if draw(st.integers(0, 3)) == 0:
        sc["shape"] = [draw(shape(mesh=False))]
    if draw(st.integers(0, 3)) == 0:
        sc["background"] = {"radiance": draw(colour)}
    return sc


# the values a fuzzed method parameter takes: within the declared range, capped where the cost grows
CHEAP = {"precision": [1e-8, 1e-4, 1e-3, 0.1], "max_iter": [1, 3, 1000], "terms": [1, 3, 6, 40], "rtol": [1e-12, 1e-6, 0.5],
         "steps": [1, 3, 64], "step": [0.0, 0.05, 1.0, 1e3], "tau_max": [1e-3, 1.0, 20.0, 700.0],
         "table_size": [2, 3, 64], "u_max": [1e-3, 1.0, 10.0, 1e3], "samples": [1, 2]}


@st.composite
def render_args(draw, methods=tuple(METHODS_BY_NAME), cheap={}):
    """(method, its parameters, volumetric shadows): each parameter drawn or left at its default;
    `methods` a tuple of names or a strategy drawing one; `cheap` overrides CHEAP's values."""
    name = draw(st.sampled_from(draw(methods) if isinstance(methods, st.SearchStrategy) else methods))
    params = {}
    for k, p in METHODS_BY_NAME[name].params.items():
        if not draw(st.booleans()):
            continue
        params[k] = draw(st.sampled_from(p.choices) if p.choices else st.booleans() if p.type is bool
                         else st.sampled_from([v for v in cheap.get(k, CHEAP[k]) if p.accepts(v)]))
    shadows = draw(st.booleans())
    if params.get("shadow_test") == "samples" and not shadows:
        shadows = draw(st.booleans())
    return name, params, shadows


def _rename(table: dict, draw) -> str:
    # not type or primitive: without them the table's other keys are the first thing wrong
    keys = sorted(set(table) - {"type", "primitive", "mesh"})
    if not keys:  # a mesh shape with nothing else, an empty interior: an unknown key
        table["colour"] = 0.5
        return "colour"
    k = draw(st.sampled_from(keys))
    bad = k + "s" if not k.endswith("s") else k[:-1]
    table[bad] = table.pop(k)
    return bad


@st.composite
def near_valid(draw, scenes=scene(), methods=tuple(METHODS_BY_NAME), cheap={}):
    """(scene, render args, spoilt scene, its render args, what its refusal must name if the scene
    itself renders): one thing spoilt; None where the spoilt scene is legal (degenerate geometry)."""
    base, base_args = draw(scenes), draw(render_args(methods, cheap))
    sc, args = copy.deepcopy(base), base_args
    return (base, base_args, *draw(_spoil(sc, args)))


@st.composite
def _spoil(draw, sc, args):
    how = draw(st.sampled_from(["misspelt", "range", "degenerate", "parameter"]))
    if how == "misspelt":
        where = draw(st.sampled_from([k for k in ("camera", "medium", "light", "shape", "interior", "layer")
                                      if k in sc or k in sc["medium"] or k in str(sc.get("shape"))]))
        if where == "interior":
            table = draw(st.sampled_from([x["interior"] for x in sc["shape"] if x.get("interior")] or [sc["camera"]]))
        elif where == "layer":
            table = draw(st.sampled_from(sc["medium"]["layer"]))
        else:
            table = sc[where] if isinstance(sc[where], dict) else draw(st.sampled_from(sc[where]))
        return sc, args, _rename(table, draw)
    if how == "range":
        spoil = draw(st.sampled_from([
            ("camera", "fov", [0.0, 180.0, -1.0]), ("camera", "width", [0, -4]), ("camera", "spp", [0]),
            ("camera", "position", [[0.0, math.inf, 0.0], [math.nan, 0.0, 0.0], [1.0, 2.0]]),
            ("medium", "sigma_s", [-1.0, math.inf, [0.1, -0.1, 0.1], 1e309]), ("medium", "sigma_a", [-1e-300]),
            ("medium", "phase", [{"type": "hg", "g": 1.0}, {"type": "hg", "g": -1.5}, "mie"]),
            ("medium", "scale_height", [0.0, -1.0]), ("medium", "profile", ["cubic"]),
            ("medium", "type", ["fog"]), ("light", "intensity", [-1.0, 1e151]), ("light", "cone_angle", [0.0, 180.0, 200.0]),
            ("light", "type", ["area"]), ("shape", "reflectance", [1.5, -0.1]), ("shape", "segments", [2, 10**9]),
            ("shape", "radius", [0.0, -1.0]), ("background", "radiance", [-1.0]),
            ("interior", "ior", [0.0, -1.33, math.inf]), ("interior", "sigma_s", [-1.0, math.nan, 1e309]),
            ("interior", "phase", [{"type": "hg", "g": 1.0}, "mie"]), ("interior", "colour", [1.0]),
            ("medium", "radius", [0.0, -1.0]), ("medium", "top_radius", [1.0, -1.0]), ("medium", "center", [[0.0, 1.0]]),
            ("layer", "scale_height", [0.0, -1.0, 1e30]), ("layer", "sigma_s", [-1.0]), ("layer", "phase", ["mie"]),
            ("layer", "name", [3.0])]))
        table, key, values = spoil
        if table == "background":
            sc["background"] = {}
        if table == "interior":  # a shape's medium
            if not sc.get("shape"):
                return sc, args, None
            shape = draw(st.sampled_from(sc["shape"]))
            shape.pop("reflectance", None)  # a shape that holds a medium has none (refused first otherwise)
            target = shape.setdefault("interior", {})
        elif table == "layer":  # an atmosphere's
            if "layer" not in sc["medium"]:
                return sc, args, None
            target = draw(st.sampled_from(sc["medium"]["layer"]))
        elif table not in sc:
            return sc, args, None
        else:
            target = sc[table] if isinstance(sc[table], dict) else draw(st.sampled_from(sc[table]))
        target[key] = draw(st.sampled_from(values))
        return sc, args, key
    if how == "degenerate":
        spoil = draw(st.sampled_from(["flat box", "point quad", "line quad", "zero cylinder", "tiny sphere",
                                      "look at self", "up along view", "grazing", "open interior"]))
        cam = sc["camera"]
        if spoil == "open interior":  # a medium in an open mesh, or in a quad: refused, naming the interior
            sc.setdefault("shape", []).append(draw(st.sampled_from([
                {"mesh": OPEN_U, "interior": {"sigma_s": 1.0}},
                {"primitive": "quad", "corners": [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
                 "interior": {}}])))
            return sc, args, "interior"
        if spoil == "flat box":
            sc.setdefault("shape", []).append({"primitive": "box", "min": [0.0, 0.0, 0.0], "max": [1.0, 0.0, 1.0]})
            return sc, args, "max"
        if spoil in ("point quad", "line quad"):
            a = draw(vec)
            b = a if spoil == "point quad" else [x + 1.0 for x in a]
            sc.setdefault("shape", []).append({"primitive": "quad", "corners": [a, a, b, b]})
        elif spoil == "zero cylinder":
            a = draw(vec)
            sc.setdefault("shape", []).append({"primitive": "cylinder", "base": a, "top": a, "radius": 1.0})
        elif spoil == "tiny sphere":
            sc.setdefault("shape", []).append({"primitive": "sphere", "center": draw(vec), "radius": 1e-300,
                                               "segments": 3})
        elif spoil == "grazing":  # camera and light on the room's ceiling, looking along it
            y = 2.0
            cam["position"][1], cam["look_at"][1] = y, y
            for x in sc.get("light", []):
                if "position" in x:
                    x["position"][1] = y
        elif spoil == "look at self":
            cam["look_at"] = list(cam["position"])
        else:
            cam["up"] = [cam["look_at"][i] - cam["position"][i] for i in range(3)]
        return sc, args, None
    name, params, shadows = args
    spoilable = [k for k, p in METHODS_BY_NAME[name].params.items() if p.choices or p.low is not None or p.high is not None]
    if not spoilable:
        return sc, (name, {"precision": 1e-3}, shadows), "precision"  # a parameter of another method
    k = draw(st.sampled_from(spoilable))
    p = METHODS_BY_NAME[name].params[k]
    bad = draw(st.sampled_from(["nonsense"] if p.choices else [v for v in (
        p.low - 1.0 if p.low is not None else None, p.low if p.open_low else None,
        p.high * 2.0 + 1.0 if p.high is not None else None, math.nan) if v is not None]))
    return sc, (name, {**params, k: bad}, shadows), k.replace("_", "-")


OUTCOMES = collections.Counter()


def check(sc, method, params, shadows, names=None):
    """Render: finite non-negative pixels, or a one-line refusal (naming `names` if given)."""
    try:
        img = raytrace.render(sc, method=method, threads=1, volumetric_shadows=shadows, **params)
    except UserError as exc:
        msg = str(exc)
        assert msg and "\n" not in msg and "this is a bug" not in msg, msg
        assert names is None or names in msg, (names, msg)
        OUTCOMES["refused"] += 1
        return None
    # lecocq returns the raw truncated Taylor polynomial, negative far from the foot point by design
    # (PP09's "negative estimates", methods/lecocq.py: FAITHFUL, NOT FIXED), and so does analytic's
    # --anisotropic taylor (the paper's eqs. 14-19) outside its convergence radius (counted in its
    # taylor_out_of_range_fraction; e.g. -3e19 with the camera on a point light): finite is all they promise
    raw = method == "lecocq" or params.get("anisotropic") == "taylor"
    assert np.all(np.isfinite(img.array)) and (raw or np.all(img.array >= 0.0)), (sc, method, params)
    if img.variance is not None:
        assert np.all(np.isfinite(img.variance)) and np.all(img.variance >= 0.0)
    OUTCOMES["rendered, lit" if np.any(img.array > 0) else "rendered, black"] += 1
    return img


def fuzz_settings(examples):
    # derandomized; shrinking on: the embreex crash after ~2000 scenes that had it turned off did not
    # recur (5000 accelerators built and dropped, or queried from fresh threads: RSS +0.1 / +2 MiB,
    # threads and mappings constant; 2000 whole renders: +14 MiB, flat after the first 400; three slow
    # runs shrinking failures for 5-10 minutes each without a crash)
    return settings(max_examples=examples, derandomize=True, deadline=None, database=None,
                    suppress_health_check=list(HealthCheck))


def _fuzz(examples, scenes=scene(), methods=tuple(METHODS_BY_NAME), cheap={}):
    @fuzz_settings(examples)
    @given(scenes, render_args(methods, cheap))
    def valid(sc, args):
        check(sc, *args)

    @fuzz_settings(examples)
    @given(near_valid(scenes, methods, cheap))
    def spoilt(case):
        base, base_args, sc, args, names = case
        rendered = check(base, *base_args) is not None
        check(sc, *args, names=names if rendered else None)

    with np.errstate(over="raise", invalid="raise", divide="raise", under="ignore"):  # a numpy warning fails too
        valid()
        spoilt()


def test_fuzzed_scenes_render_or_refuse():
    _fuzz(30)


# the methods that take an atmosphere (analytic, lecocq, sun and slab_approx refuse it in one line, which
# the scenes above check): most atmosphere scenes go to these, a few to any method
ATMOSPHERE_METHODS = st.sampled_from([("quadrature", "raymarch", "montecarlo")] * 4 + [tuple(METHODS_BY_NAME)])
# raymarch's step by count only: a 0.05 m step across a planet is ~1e8 steps per ray (170 s for 12 pixels)
ATMOSPHERE_CHEAP = {"step": [0.0]}


def test_fuzzed_atmospheres_render_or_refuse():
    _fuzz(10, planet_scene(), ATMOSPHERE_METHODS, ATMOSPHERE_CHEAP)


@pytest.mark.slow
def test_fuzzed_scenes_render_or_refuse_many():
    OUTCOMES.clear()
    _fuzz(1000)
    print(f"\nfuzzed scenes: {dict(OUTCOMES)}")
    assert OUTCOMES["rendered, lit"] >= 100  # not vacuous


@pytest.mark.slow
def test_fuzzed_atmospheres_render_or_refuse_many():
    OUTCOMES.clear()
    _fuzz(1000, planet_scene(), ATMOSPHERE_METHODS, ATMOSPHERE_CHEAP)
    print(f"\nfuzzed atmospheres: {dict(OUTCOMES)}")
    assert OUTCOMES["rendered, lit"] >= 100  # not vacuous


inside = st.floats(-1.75, 1.75)
inside_vec = st.tuples(inside, inside, inside).map(list)
coefficient = st.floats(0.01, 2.0)
away = inside_vec.filter(lambda v: max(abs(v[0]), abs(v[2])) > 0.1)  # a view or spot axis, not along up
# held to their law on every lit scene; lecocq and sun (the papers' approximations: an unclamped Taylor
# polynomial in angle, a bilinear table) are only measured: their declared laws (median 0.75, 3e-4)
# hold on the oracle's box rooms but not here (measured medians up to 4e4 and 1.7e-3 on 150 scenes:
# lecocq's polynomial diverges far from the foot point, sun's table is coarse near the light's line)
HELD = ("analytic", "raymarch")
MEASURED = ("lecocq", "sun")
WORST = {}


@st.composite
def lit_scene(draw):
    """A lit, moderately thick box room: camera and 1-2 point or spot lights inside (not within 0.1 of
    the camera: on it the air-light is the regularisation's, geometry.py, which no sampling resolves), sigma_t from
    0.01 to 4 per unit (optical depths ~0.01 ... 30 across the room), any phase, walls of any
    reflectance, sometimes an occluder (a sphere or a quad) for the volumetric shadows."""
    pos, view = draw(inside_vec), draw(away)
    lights = draw(st.lists(light(kinds=("point", "spot")), min_size=1, max_size=2))
    for x in lights:  # off the camera: there the air-light is infinite, a regularisation's convention
        x["position"] = draw(inside_vec.filter(lambda v: math.dist(v, pos) > 0.1))
        x["intensity"] = draw(st.floats(0.1, 100.0))
        if "look_at" in x:
            x["look_at"] = [p + v for p, v in zip(x["position"], draw(away))]
        elif "direction" in x:  # not zero
            x["direction"] = draw(away)
    cam = {"type": draw(st.sampled_from(["perspective", "environment"])), "position": pos,
           "look_at": [p + v for p, v in zip(pos, view)], "width": 4, "height": 3, "spp": 1}
    med = {"sigma_a": draw(st.one_of(st.just(0.0), coefficient)),
           "sigma_s": draw(st.one_of(coefficient, st.tuples(coefficient, coefficient, coefficient).map(list))),
           "phase": draw(phase)}
    sc = box_room(camera=cam, light=lights, medium=med)
    sc["shape"][0]["reflectance"] = draw(colour)
    occluder = draw(st.sampled_from([None, "sphere", "quad"]))
    if occluder == "sphere":
        sc["shape"].append({"primitive": "sphere", "center": draw(inside_vec), "radius": draw(st.floats(0.1, 0.8)),
                            "segments": 8})
    elif occluder == "quad":
        y = draw(inside)
        sc["shape"].append({"primitive": "quad", "corners": [[-1.0, y, -2.0], [1.0, y, -2.0], [1.0, y, 0.0],
                                                             [-1.0, y, 0.0]]})
    if occluder == "sphere" and not shadows_only(sc) and draw(st.booleans()):  # a bounded medium (seed 002)
        sph = sc["shape"][-1]
        if all(math.dist(x["position"], sph["center"]) > sph["radius"] + 0.05 for x in lights):
            sph["interior"] = {"sigma_a": draw(st.one_of(st.just(0.0), coefficient)), "sigma_s": draw(coefficient),
                               "phase": draw(phase)}
    return sc


def shadows_only(sc) -> bool:
    """Spot lights: media inside shapes do not take them (interiors/support.py refuses them in one line)."""
    return any(x.get("type") == "spot" for x in sc["light"])


@st.composite
def lit_planet(draw):
    """A small planet's atmosphere lit by the sun above the horizon (tests/test_atmosphere.py's SMALL:
    R = 1 km, 75 m of air, Rayleigh and Mie layers of Earth's optical depths, scaled by 0.1 to 10), the
    camera on the ground or in the air looking anywhere: for raymarch's order against quadrature."""
    radius, f = 1000.0, draw(st.sampled_from([0.1, 1.0, 10.0]))
    med = {"type": "atmosphere", "center": [0.0, -radius, 0.0], "radius": radius, "top_radius": radius + 75.0,
           "reflectance": draw(colour),
           "layer": [{"sigma_s": [4.6e-3 * f, 1.08e-2 * f, 2.65e-2 * f], "scale_height": 10.0, "phase": draw(phase)},
                     {"sigma_s": 3.2e-3 * f, "sigma_a": 3.6e-4 * f, "scale_height": 1.5, "phase": draw(phase)}]}
    pos = [0.0, draw(st.sampled_from([0.5, 5.0, 40.0])), 0.0]
    view = draw(st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: abs(v[0]) + abs(v[2]) > 0.1))
    sun = [draw(st.floats(-1.0, 1.0)), -draw(st.floats(0.3, 1.0)), draw(st.floats(-1.0, 1.0))]
    return {"camera": {"type": draw(st.sampled_from(["perspective", "environment"])), "position": pos,
                       "look_at": [p + v for p, v in zip(pos, view)], "width": 4, "height": 3, "spp": 1},
            "light": [{"type": "directional", "direction": sun, "irradiance": draw(st.floats(0.1, 20.0))}],
            "medium": med}


def law_statistic(law, img, ref, base=None):
    """The law's statistic (tests/test_methods.py) of `img` against `base` (default: the quadrature
    image `ref`), relative to `ref`, over the pixels `ref` lights."""
    lit = ref > 0
    rel = np.abs(img - (ref if base is None else base))[lit] / ref[lit]
    return float(rel.max() if law.statistic == "max" else np.median(rel)) if lit.any() else 0.0


def check_laws(sc, shadows):
    """Every method of HELD that takes the scene meets its law against quadrature (MEASURED ones
    record their worst statistic in WORST); returns the number of comparisons made. raymarch is held
    to its order, O(h^2) (midpoint rule, exact lit intervals): at ORDER_STEPS n, 2n, 4n its error at
    4n is at most what that order allows from either coarser count (e(2n) / ORDER_RATIO or
    e(n) / ORDER_RATIO^2: an error that crosses zero at 2n, as the irregular O(h^3) error of a narrow
    spot's bump, whose leading term vanishes, does, is not held to its own accidental smallness).
    A failure says whether the steps' changes still shrink at that order (then raymarch converges,
    to the wrong value: a step-independent floor, such as 8e-9 of light leaking into a closed sphere,
    1.3e-9 off quadrature at every step count) or not (its order). Its declared absolute law (median
    5e-8 at 4096 steps) was measured on the oracle's scenes and does not carry over to thick media,
    where the error scales as (kt h)^2: 8e-7 measured on these scenes."""
    ref = raytrace.render(sc, method="quadrature", threads=1, volumetric_shadows=shadows,
                          **METHODS_BY_NAME["quadrature"].error_law.params).array
    OUTCOMES["lit" if np.any(ref > 0) else "black"] += 1
    floor = falloff_floor(sc)
    done = 0
    for name in HELD + MEASURED:
        law = METHODS_BY_NAME[name].error_law
        try:
            if name == "raymarch":
                r1, r2, r4 = (raytrace.render(sc, method=name, threads=1, volumetric_shadows=shadows, steps=n).array
                              for n in ORDER_STEPS)
                verdict = order_verdict([law_statistic(law, r, ref) for r in (r1, r2, r4)],
                                        [law_statistic(law, r1, ref, r2), law_statistic(law, r2, ref, r4)], floor)
                assert verdict is None, f"raymarch, {verdict} on {sc} shadows={shadows}"
            else:
                img = raytrace.render(sc, method=name, threads=1, volumetric_shadows=shadows, **law.params).array
                value = law_statistic(law, img, ref)
                WORST[name] = max(WORST.get(name, 0.0), value)
                assert name in MEASURED or value <= law.tolerance + floor, \
                    f"{name}: {law.statistic} {value:.3g} > {law.tolerance:g} on {sc} shadows={shadows}"
        except UserError as exc:  # a light, phase or bounded medium the method does not take, said so
            assert "--method" in str(exc) or "method " in str(exc) or "interior" in str(exc), str(exc)
            continue
        OUTCOMES[name] += 1
        done += 1
    return done


def order_verdict(errors, changes, floor=0.0):
    """None if the errors at ORDER_STEPS (n, 2n, 4n) meet O(h^2) (`check_laws`), else what failed:
    a step-independent floor (the changes between counts still shrink by ORDER_RATIO) or the order."""
    e1, e2, e4 = errors
    if e4 <= max(e1 / ORDER_RATIO**2, e2 / ORDER_RATIO) + ORDER_FLOOR + floor:
        return None
    what = "a step-independent floor" if changes[1] <= changes[0] / ORDER_RATIO else "not its order"
    return f"{what}: median error {e1:.3g}, {e2:.3g}, {e4:.3g} at {ORDER_STEPS} steps, changes {changes[0]:.3g}, " \
           f"{changes[1]:.3g}"


def test_the_order_check_tells_a_floor_from_an_order():
    """Errors F + C/n^2 against a reference, at n = 512, 1024, 2048: a clean second order passes, also
    when its error crosses zero at 2n; a first order fails as such; a floor fails as a floor."""
    n = np.array(ORDER_STEPS, float)

    def verdict(values):
        return order_verdict(np.abs(values), np.abs(np.diff(values)))

    assert verdict(1e-3 / n**2) is None
    # a narrow spot's pixel (cone 1 degree), measured at 256, 512, 1024 steps: its error crosses zero near 2n
    assert verdict(np.array([3.6976e-9, 3.9e-11, 1.966e-10])) is None
    assert verdict(1e-3 / n).startswith("not its order")
    assert verdict(1.3e-9 + 1e-3 / n**2).startswith("a step-independent floor")


def falloff_floor(sc) -> float:
    """The relative accuracy every method shares in a scene with narrow spots: the falloff is a
    smoothstep in the cosine to the axis (lights.py) whose argument divides by about 1 - cos(cone)
    = 2 sin^2(cone / 2), so rounding of the cosine (eps) becomes eps / (1 - cos) of it; 10 times that
    (a 0.001-degree cone: 1.5e-5; measured floors: raymarch 9e-8 at every step count, analytic 2e-7;
    0.01 degrees: 2e-9)."""
    cones = [math.radians(x["cone_angle"]) for x in sc.get("light", []) if x.get("type") == "spot"]
    return max([10.0 * 2.2e-16 / (2.0 * math.sin(c / 2.0) ** 2) for c in cones], default=0.0)


ORDER_STEPS = (512, 1024, 2048)
ORDER_RATIO = 3.6  # measured 4.00 (16 where the leading term vanishes by symmetry) on 40 scenes
ORDER_FLOOR = 1e-12  # the reference's own error (quadrature's law: 3e-13)


def _agree(examples, scenes=lit_scene()):
    @fuzz_settings(examples)
    @given(scenes, st.booleans())
    def agree(sc, shadows):
        check_laws(sc, shadows)

    agree()


def test_deterministic_methods_meet_their_law_on_fuzzed_lit_scenes():
    _agree(12)


def test_raymarch_meets_its_order_on_fuzzed_lit_atmospheres():
    _agree(3, lit_planet())


@pytest.mark.slow
def test_deterministic_methods_meet_their_law_on_fuzzed_lit_scenes_many():
    OUTCOMES.clear()
    _agree(300)
    _agree(40, lit_planet())
    print(f"\nlit scenes (reference images lit / black) and comparisons per method: {dict(OUTCOMES)}; "
          f"worst statistic of the measured methods: {WORST}")


CAMERA_ON_SPOT_IN_ULTRA_DENSE_MEDIUM = box_room(
    camera={"type": "perspective", "position": [0.6147737503051758, -1.8686078786849976, 0.0],
            "look_at": [0.0, 0.15902665257453918, 0.4994328022003174], "width": 4, "height": 3, "spp": 1},
    light=[{"position": [0.6147737503051758, -1.8686078786849976, 0.0], "intensity": [1e150, 1e30, 1e6],
            "type": "spot", "direction": [1.1749484539031982, 1e-07, 0.0], "cone_angle": 97.44712180942933,
            "falloff_start": 94.07409015299417}],
    medium={"sigma_a": 1.0, "sigma_s": 1e300, "phase": "isotropic"})


def test_regression_ultra_dense_height_fog_renders_black_without_a_warning():
    """Was a numpy 'overflow in multiply' (the fuzzer): a height fog of sigma_a up to 1e300 and scale
    height 1e-300, the camera far below h0 (a linear profile's density ~1e300 there): kt tau
    overflows to inf in the transmittance, whose exp(-inf) = 0 is exact. Every optical path here is
    beyond 1e299, so the image is exactly 0."""
    sc = box_room(camera={"type": "environment", "position": [2.0, -1.9, 0.0], "look_at": [-3.0, 4.0, 0.0],
                          "width": 4, "height": 3},
                  light=[{"position": [2.0, -1.9, 0.0], "intensity": 1e30}],
                  medium={"type": "height_fog", "sigma_a": [1e30, 1.0, 1e300], "sigma_s": 0.1, "scale_height": 1e-300,
                          "up": [2.0, 4.0, 0.95], "profile": "linear"})
    for method in ("quadrature", "raymarch", "montecarlo"):
        with np.errstate(over="raise", invalid="raise", divide="raise"):
            img = raytrace.render(sc, method=method, threads=1)
        assert np.array_equal(img.array, np.zeros_like(img.array)), method


def test_regression_camera_on_a_spot_light_in_an_ultra_dense_medium():
    """Was NaN: the segments start at the light, whose distance to the ray line is clamped to the
    regularisation radius h (methods/geometry.py) while d_a stayed 0, so analytic's optical path
    started at 0 instead of h (e^0 against e^{-kt h} = 0). Every exp(-1e300 x) is 0 here: so is the image."""
    img = raytrace.render(CAMERA_ON_SPOT_IN_ULTRA_DENSE_MEDIUM, method="analytic", threads=1,
                          volumetric_shadows=True, precision=1e-4)
    assert np.array_equal(img.array, np.zeros_like(img.array))


@pytest.mark.parametrize("light", [{}, {"type": "spot", "direction": [0.0, 0.0, -1.0], "cone_angle": 60.0,
                                        "falloff_start": 40.0}], ids=["point", "spot"])
@pytest.mark.parametrize("sigma_s", [1e6, 1e8, 1e10])
def test_regression_camera_on_a_light_analytic_meets_its_law(light, sigma_s):
    """The same cause away from underflow: a camera on a light in a medium with kt h from 5e-3 to 50
    (h the 5e-9 m regularisation radius). Before the fix analytic was 0.4 % (1e6), 49 % (1e8) and
    2e17 times (1e10) off quadrature; now within its declared law (methods/__init__.py ErrorLaw)."""
    law = METHODS_BY_NAME["analytic"].error_law
    sc = box_room(light=[{"position": [0.3, 0.2, 3.0], "intensity": 10.0, **light}],
                  medium={"sigma_a": 0.0, "sigma_s": sigma_s, "phase": "isotropic"},
                  camera={"type": "perspective", "position": [0.3, 0.2, 3.0], "look_at": [0.0, 0.0, -1.0],
                          "fov": 70.0, "width": 4, "height": 3, "spp": 1})
    ref = raytrace.render(sc, method="quadrature", threads=1, **METHODS_BY_NAME["quadrature"].error_law.params).array
    img = raytrace.render(sc, method="analytic", threads=1, **law.params).array
    assert np.all(ref > 0)
    assert np.max(np.abs(img - ref) / ref) <= law.tolerance


def test_regression_a_planet_seen_from_beyond_float64_reach_renders():
    """Was a ZeroDivisionError in the compiled atmosphere.ray_transmittance, found by the slow fuzz
    run: a cylinder scaled by 1e30 beside a planet of radius 100; its shadow rays toward a light on
    the ground start 7e29 away, straight at the centre, and their end rounds onto it (chapman._lift)."""
    sc = {"camera": {"type": "perspective", "position": [0.0, 1e-07, 0.0], "look_at": [0.0, 1e-07, 100.0],
                     "width": 4, "height": 3, "spp": 1},
          "medium": {"type": "atmosphere", "center": [0.0, -100.0, 0.0], "radius": 100.0, "top_radius": 100.01,
                     "layer": [{"sigma_s": 0.0, "scale_height": 0.001, "phase": "isotropic"}]},
          "light": [{"type": "point", "position": [0.0, 1e-07, 0.0], "intensity": 1.0}],
          "shape": [{"primitive": "cylinder", "radius": 1e-06, "segments": 3, "base": [0.0, 0.0, 1.0],
                     "top": [1.0, 0.0, 0.0], "transform": {"scale": 1e30}}],
          "background": {"radiance": 0.0}}
    for method in ("quadrature", "raymarch", "montecarlo"):
        with np.errstate(over="raise", invalid="raise", divide="raise", under="ignore"):
            check(sc, method, {}, False)


@pytest.mark.parametrize("shadow_test", ["intervals", "samples"])
def test_regression_raymarch_in_a_subnormal_medium(shadow_test):
    """Was NaN pixels ("this is a bug", lit intervals) or numpy 'invalid value in divide' (shadow ray
    per sample), found by the slow fuzz run: rays that hit nothing march to tau_max / kt, which
    overflowed to inf for sigma_s = 1e-310; the march now ends at raymarch.MAX_END at most."""
    sc = {"camera": {"type": "perspective", "position": [0.0, 1.0, 0.0], "look_at": [0.0, 0.0, 0.0], "width": 4,
                     "height": 3, "up": [0.0, 0.0, 1.0]},
          "shape": [{"primitive": "box", "min": [0.0, 0.0, 0.0], "max": [1e-06, 1e-06, 1e-06]}],
          "light": [{"position": [0.0, 0.0, 0.0], "intensity": 1.0}],
          "medium": {"sigma_a": 0.0, "sigma_s": 1e-310, "phase": "isotropic"}}
    with np.errstate(over="raise", invalid="raise", divide="raise"):
        img = raytrace.render(sc, method="raymarch", threads=1, volumetric_shadows=True, shadow_test=shadow_test)
    assert np.all(np.isfinite(img.array)) and np.all(img.array >= 0.0)
    assert np.all(img.array < 1e-300)  # at most ks I pi / (4 pi h) ~ 1e-310 / h, h > 0.1 here


def test_regression_montecarlo_shadow_samples_of_a_huge_light_on_the_camera():
    """Was numpy's 'overflow encountered in square', found by the slow fuzz run: a light of 1e150 on the
    camera gives shadow-tested estimates whose variance is beyond float64 (shadow_rays.py): inf there
    (the estimator's spread is not representable), and the render is refused in one line, as every
    image beyond float32's range is."""
    sc = {"camera": {"type": "perspective", "position": [0.0, 0.0, 1.0], "look_at": [0.0, 0.0, 0.0], "width": 4,
                     "height": 3},
          "shape": [{"primitive": "box", "min": [0.0, 0.0, 0.0], "max": [1e-06, 1e-06, 1e-06]}],
          "light": [{"position": [0.0, 0.0, 1.0], "intensity": 1e150}],
          "medium": {"sigma_a": 0.0, "sigma_s": 1.0, "phase": "rayleigh"}}
    with np.errstate(over="raise", invalid="raise", divide="raise", under="ignore"):
        with pytest.raises(UserError, match="exceed float32's 3.4e38 .* move the camera off the light"):
            raytrace.render(sc, method="montecarlo", threads=1, volumetric_shadows=True, shadow_test="samples")


def test_regression_a_medium_in_a_shape_of_zero_area_is_refused():
    """Was a numpy 'Mean of empty slice' (bounded.warm_up_rays) and 'invalid value in divide', found by
    the fuzzer: a quad whose corners coincide holds an interior; its degenerate triangles cancel each
    other's edges (so it passed as closed) and are then dropped, leaving the medium no triangles."""
    sc = {"camera": {"position": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, 1.0], "width": 4, "height": 3},
          "shape": [{"primitive": "quad", "corners": [[0.0, 0.0, 0.0]] * 4, "interior": {}}],
          "medium": {"sigma_a": 0.0, "sigma_s": 0.0}}
    with pytest.raises(UserError, match=r"shape\[0\]\.interior: every triangle of the shape has zero area"):
        raytrace.render(sc, method="analytic", threads=1)


CAMERA_IN_SMALL_SPHERE = box_room(
    camera={"type": "environment", "position": [0.17034552406761497, -0.32376866595581505, 0.12503646726300527],
            "look_at": [0.17034552406761497, -0.12376866595581504, 1.1250364672630053], "width": 8, "height": 6},
    light=[{"position": [1.0, 1.0, -1.0], "intensity": 10.0}, {"position": [-1.5, -1.0, 1.5], "intensity": 5.0}],
    medium={"sigma_a": 0.05, "sigma_s": 0.5, "phase": "isotropic"})
CAMERA_IN_SMALL_SPHERE["shape"].append({"primitive": "sphere", "center": [0.2, -0.3, 0.1], "radius": 0.1,
                                        "segments": 8})


@pytest.mark.parametrize("method", sorted(METHODS_BY_NAME))
@pytest.mark.parametrize("sun", [False, True])
def test_regression_no_light_reaches_the_inside_of_a_closed_sphere(method, sun):
    """Found by the slow fuzz run: a camera inside a small closed sphere (radius 0.1, 8 segments),
    the lights outside, volumetric shadows on: pixel (2, 7) saw 1.9e-10 of light, because the last
    point of its segment (on the far wall) was tested by a shadow ray stopped the shadow-ray offset
    (4e-5) short of it, and the near wall crossed the light's ray 1.2e-5 before it. Every method
    must render black; with the sun (a height fog, which takes directional lights) likewise, a guard
    of its own end-point test (no failing sun case was found at this resolution)."""
    sc = copy.deepcopy(CAMERA_IN_SMALL_SPHERE)
    if sun:
        sc["light"] = [{"type": "directional", "direction": [-1.0, -1.0, 1.0], "irradiance": 3.0},
                       {"type": "directional", "direction": [1.5, 1.0, -1.5], "irradiance": 2.0}]
        sc["medium"].update(type="height_fog", scale_height=2.0)
    try:
        img = raytrace.render(sc, method=method, threads=1, volumetric_shadows=True)
    except UserError as exc:  # a light or medium the method does not take, said so
        assert "--method" in str(exc) or "method " in str(exc), str(exc)
        return
    assert img.array.max() == 0.0, np.argwhere(img.array.max(axis=2) > 0).tolist()
