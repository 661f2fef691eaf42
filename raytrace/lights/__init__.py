"""What a light is: one module per kind (point.py, spot.py with its falloff curves and cone
mathematics, directional.py) behind the interface of light.py, and the arrays kernels read (`Lights`).

`KINDS` maps the scene files' `light.type` to the kind; `parse_light` reads a [[light]] table,
`describe` says what a light is; `light_sample` is the kernels' one entry to the kinds' samples
(light.py): kernels may tell a positional sample from a distant one (dist = inf), never one kind
from another.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..jit import njit
from . import directional, point, spot
from .light import NO_CONE, Light
from .spot import (CURVES, GLTF, MITSUBA, SMOOTHSTEP, band_slope, band_trig, cone_breaks, falloff, falloff_array,
                   is_spot, polynomial_band, segment_cone)

KINDS = {kind.NAME: kind for kind in (point, spot, directional)}
_BY_CODE = {kind.CODE: kind for kind in KINDS.values()}
NAMES = {code: kind.NAME for code, kind in _BY_CODE.items()}
POINT, SPOT, DIRECTIONAL = point.CODE, spot.CODE, directional.CODE


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


@dataclass(frozen=True)
class Lights:
    """All lights as float64 arrays: `kind` (L,), `position` (L, 3), `intensity` (L, 3), `axis` (L, 3)
    (zero for point lights), `cone` (L, 3): (cos_end, cos_start, curve), NO_CONE for point and
    directional lights (their curve: SMOOTHSTEP, unused)."""
    kind: np.ndarray
    position: np.ndarray
    intensity: np.ndarray
    axis: np.ndarray
    cone: np.ndarray

    @classmethod
    def of(cls, lights: list[Light]) -> "Lights":
        axis = [np.zeros(3) if l.axis is None else l.axis for l in lights]
        return cls(np.array([l.kind for l in lights], dtype=np.int64),
                   np.array([l.position for l in lights], dtype=float).reshape(-1, 3),
                   np.array([l.intensity for l in lights], dtype=float).reshape(-1, 3),
                   np.array(axis, dtype=float).reshape(-1, 3),
                   np.array([(l.cos_end, l.cos_start, l.curve) for l in lights], dtype=float).reshape(-1, 3))

    def __len__(self) -> int:
        return len(self.kind)

    def kinds(self) -> set[str]:
        return {NAMES[int(k)] for k in self.kind}

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


__all__ = ["CURVES", "DIRECTIONAL", "GLTF", "KINDS", "Light", "Lights", "MITSUBA", "NAMES", "NO_CONE", "POINT",
           "SMOOTHSTEP", "SPOT", "band_slope", "band_trig", "cone_breaks", "describe", "falloff", "falloff_array",
           "is_spot", "light_sample", "parse_light", "polynomial_band", "segment_cone"]
