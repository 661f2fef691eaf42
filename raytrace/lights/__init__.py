"""What a light is: one module per kind (point.py, spot.py with its falloff curves and cone
mathematics, directional.py; the area lights quad.py, disk.py, sphere.py, area.py; the environment,
environment.py, whose rows are directional) behind the
interface of light.py, and the arrays kernels read (`Lights`: each scene light's rows, an area
light's emitter points being spot rows).

`KINDS` maps the scene files' `light.type` to the kind; `parse_light` reads a [[light]] table,
`describe` says what a light is; `light_sample` is the kernels' one entry to the kinds' samples
(light.py): kernels may tell a positional sample from a distant one (dist = inf), never one kind
from another. `at_infinity` is what a camera ray that leaves the scene sees (the environment light's
radiance, else the [background]).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..jit import njit
from . import cubature, directional, disk, emissive, environment, point, quad, sphere, spot
from .area import Emitter, emitter, power_of, two_sided
from .light import NO_CONE, Light, power
from .spot import (CURVES, GLTF, LAMBERT, MITSUBA, SMOOTHSTEP, band_slope, band_trig, cone_breaks, falloff,
                   falloff_array, has_cone, polynomial_band, segment_cone)

KINDS = {kind.NAME: kind for kind in (point, spot, directional, quad, disk, sphere, environment)}
_BY_CODE = {kind.CODE: kind for kind in KINDS.values()}
NAMES = {code: kind.NAME for code, kind in _BY_CODE.items()}
POINT, SPOT, DIRECTIONAL = point.CODE, spot.CODE, directional.CODE
AREA = (quad.NAME, disk.NAME, sphere.NAME)  # the kinds whose rows are a cubature of an emitter (area.py)
EXPANDED = AREA + (environment.NAME,)  # the kinds whose rows are other kinds' rows (emitter points, directions)
EMISSION = emissive.NAME  # emissive shapes among the kinds (`Lights.kinds`)
ENVIRONMENT = environment.NAME
DISTANT = (directional.CODE, environment.CODE)  # the kinds of scene lights at infinity (no position)


def parse_light(read, i, raw) -> Light:
    """Light i of a scene file's [[light]] tables, through `read` (scene/format.py's); a light
    without a `type` is a point light."""
    key = f"light[{i}]"
    raw = read.table(key, raw)
    kind = KINDS[read.string(f"{key}.type", raw.get("type", point.NAME), tuple(KINDS))]
    read.unknown(key, raw, kind.KEYS)
    return kind.parse(read, key, raw)


def describe(light: Light) -> str:
    """What `render.py describe` prints for a light, after "light[i]: "."""
    return _BY_CODE[light.kind].describe(light)


def distant(light: Light) -> bool:
    """Whether a scene light is at infinity (a directional or environment light: no position)."""
    return light.kind in DISTANT


def at_infinity(lights: list[Light], background, dirs) -> np.ndarray:
    """Radiance (N, 3) that camera rays of unit directions `dirs` (N, 3) see where they leave the
    scene: the environment light's (`radiance` of its kind), else the constant `background`."""
    for light in lights:
        kind = _BY_CODE[light.kind]
        if hasattr(kind, "radiance"):
            return kind.radiance(light, dirs)
    return np.broadcast_to(np.asarray(background, float), (len(dirs), 3))


def check_at_infinity(read, lights: list[Light], background: bool):
    """Refuse (read.fail) a second light seen at infinity, or one beside a [background] table."""
    seen = [i for i, light in enumerate(lights) if hasattr(_BY_CODE[light.kind], "radiance")]
    if len(seen) > 1:
        read.fail(f"light[{seen[1]}].type", f"a second environment light (light[{seen[0]}] is one)",
                  "keep one (scale it or merge the maps)")
    if seen and background:
        read.fail("background", f"given with an environment light (light[{seen[0]}]), which replaces it",
                  "remove the [background] table")


def emitter_shape(light: Light):
    """(primitive, params) of an area light's emitter as a [[shape]] (scene/format.py adds it), else None."""
    kind = _BY_CODE[light.kind]
    return kind.shape(light) if hasattr(kind, "shape") else None


def _emitter(light: Light):
    """The `area.Emitter` of a scene light whose kind samples its emitter (`sample_emitter`, with the
    parameters of its corners `CORNERS`, its `planar` or `ball` geometry and its `surface_irradiance`
    where it has them), else None."""
    kind = _BY_CODE[light.kind]
    if not hasattr(kind, "sample_emitter"):
        return None
    return emitter(light, kind.sample_emitter, getattr(kind, "CORNERS", None), getattr(kind, "planar", None),
                   getattr(kind, "ball", None), getattr(kind, "surface_irradiance", None), kind.rows)


def cubature_ladders(lights: list[Light], emitters=()):
    """(ladders, counts) of `Lights.of`'s sources for the pilot (cubature.py): per source its orders
    (None: not a cubature of an emitter) and the function order -> its rows (each order's counted once)."""
    ladders, counts = [], []
    remembered = functools.lru_cache(maxsize=None)
    for l in lights:
        kind = _BY_CODE[l.kind]
        count = remembered(lambda o, kind=kind, l=l: len(kind.rows(l, o).kind)) if kind.NAME in AREA else None
        ladders.append(None if count is None else cubature.ladder(cubature.AREA_LADDER, count))
        counts.append(count)
    for tris, _, two, _ in emitters:
        count = remembered(lambda o, tris=tris, two=two: emissive.count(tris, two, o))
        ladders.append(cubature.ladder(emissive.levels(len(tris), cubature.LEVELS), count))
        counts.append(count)
    return ladders, counts


def _stack(rows, name, width, dtype=float):
    """The `name` arrays of light.Rows stacked: (L, width), or (L,) for width 0."""
    shape = (-1, width) if width else (-1,)
    return np.concatenate([np.asarray(getattr(r, name), dtype).reshape(shape) for r in rows] +
                          [np.zeros((0, width) if width else (0,), dtype)])


@dataclass(frozen=True)
class Lights:
    """The rows the kernels see (one per point, spot or directional light, an area light's emitter
    points, an environment light's directions: light.py `rows`) as float64 arrays: `kind` (L,) the
    row's kind (point, spot or directional), `position` (L, 3), `intensity` (L, 3), `axis` (L, 3) (zero
    for point lights), `cone` (L, 3): (cos_end, cos_start, curve), NO_CONE for point and directional
    lights (their curve: SMOOTHSTEP, unused); `owner` (L,) the scene light of each row (its index in the
    scene's lights; an emissive shape's rows: the number of lights plus its index among the emissive
    shapes), `cubature` (L,) whether the row is a node of an emitter's cubature or an environment's
    direction (no error bound), and `scene_kinds` the scene lights' kinds (then "emission" per emissive
    shape)."""
    kind: np.ndarray
    position: np.ndarray
    intensity: np.ndarray
    axis: np.ndarray
    cone: np.ndarray
    owner: np.ndarray
    cubature: np.ndarray
    scene_kinds: tuple = ()
    emitters: tuple = ()

    @classmethod
    def of(cls, lights: list[Light], emitters=(), orders=None, sources=None) -> "Lights":
        """The rows of the scene's `lights`, then of its emissive shapes: `emitters`, a list of
        (world triangles (T, 3, 3), emission, two_sided, the shape's key for a refusal); `orders`:
        per source (the lights, then the emitters) its rule's order (`cubature_ladders`; None: the
        kind's default); `sources`: the `emitters` tuple of a `Lights` of the same lights and shapes
        at other orders (the pilot's: their rules built once), else built here."""
        orders = orders or (None,) * (len(lights) + len(emitters))
        rows = ([_BY_CODE[l.kind].rows(l, o) if o is not None else _BY_CODE[l.kind].rows(l)
                 for l, o in zip(lights, orders)] +
                [emissive.rows(*e, o) for e, o in zip(emitters, orders[len(lights):])])
        counts = [len(r.kind) for r in rows]
        return cls(_stack(rows, "kind", 0, np.int64), *(_stack(rows, k, 3) for k in ("position", "intensity", "axis",
                                                                                     "cone")),
                   np.repeat(np.arange(len(rows), dtype=np.int64), counts),
                   np.repeat(np.array([r.cubature for r in rows], dtype=bool), counts),
                   tuple(NAMES[l.kind] for l in lights) + (EMISSION,) * len(emitters),
                   sources if sources is not None else
                   tuple(_emitter(l) for l in lights) + tuple(emissive.emitter(*e) for e in emitters))

    def __len__(self) -> int:
        return len(self.kind)

    @cached_property
    def distant(self) -> np.ndarray:
        """(L,) whether each row is a distant sample (a direction, no position: a directional light's,
        an environment's); the rest are positional (a point, a spot, an emitter's node). Code outside
        this package tells rows apart by this, never by their kind."""
        return self.kind == directional.CODE

    def kinds(self) -> set[str]:
        """The kinds of the scene's lights and of the rows they give (an area light's: spot)."""
        return set(self._kinds)

    def cones(self) -> bool:
        """Whether any row shines in a cone (a spot light's, an emitter's node: its Lambertian
        half-space): code outside this package asks this, not for a kind, to cut segments to cones and
        to compile the kernels of their bands."""
        return self._cones

    @cached_property
    def _cones(self) -> bool:
        """`cones`, once per rows (without `_kinds`' set: asked of every batch of emitter samples)."""
        return bool(np.any(self.kind == spot.CODE)) or spot.NAME in self.scene_kinds

    @cached_property
    def _kinds(self) -> frozenset[str]:
        return frozenset({NAMES[int(k)] for k in np.unique(self.kind)} | set(self.scene_kinds))

    def unbounded(self) -> list[str]:
        """Why the cubature rows give no error bound, once per reason: "area lights' cubature", "the
        environment's directions"."""
        kinds = [self.scene_kinds[o] for o in np.unique(self.owner[self.cubature])]
        return list(dict.fromkeys("the environment's directions" if k == ENVIRONMENT else "area lights' cubature"
                                  for k in kinds))

    def irradiance(self, index: int, to_points: np.ndarray, dist: np.ndarray) -> np.ndarray:
        """Unattenuated irradiance (N, 3) from light `index` on surfaces facing it at the points
        light + to_points (N, 3), at distances `dist` (N,) > 0 (a directional light's: its own)."""
        return _BY_CODE[int(self.kind[index])].irradiance(self, index, to_points, dist)


@njit
def light_sample(kind, position, axis, cone, li, px, py, pz):
    """(ux, uy, uz, dist, weight): light li (the `Lights` arrays `kind`, `position`, `axis`, `cone`)
    seen from the point p, its kind's `sample` (light.py): the unit direction toward the light, its
    distance (inf: a distant sample) and its weight: the unattenuated irradiance at p on a surface
    facing the light is intensity weight / dist^2, a distant sample's intensity weight;
    (0, 0, 0, 0, 0) at a point or spot light's own position."""
    k = kind[li]
    if k == directional.CODE:
        return directional.sample(position, axis, cone, li, px, py, pz)
    if k == spot.CODE:
        return spot.sample(position, axis, cone, li, px, py, pz)
    return point.sample(position, axis, cone, li, px, py, pz)


__all__ = ["AREA", "CURVES", "DIRECTIONAL", "EMISSION", "Emitter", "ENVIRONMENT", "EXPANDED", "GLTF", "KINDS", "LAMBERT", "Light", "Lights",
           "MITSUBA", "NAMES", "NO_CONE", "POINT", "SMOOTHSTEP", "SPOT", "at_infinity", "band_slope", "band_trig",
           "check_at_infinity", "cone_breaks", "cubature", "cubature_ladders", "describe", "distant", "emitter_shape", "falloff", "falloff_array",
           "has_cone", "light_sample", "parse_light", "polynomial_band", "power", "power_of", "segment_cone",
           "two_sided"]
