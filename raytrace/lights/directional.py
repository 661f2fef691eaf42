"""The directional light (the sun): no position; `axis` is its direction of travel and `intensity`
its irradiance E per channel on a surface facing it, outside any medium. Its one sample is distant.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .light import Light, one_row, power

NAME = "directional"
CODE = 2
KEYS = frozenset({"type", "direction", "irradiance"})
rows = one_row  # its own one sample


def parse(read, key, raw) -> Light:
    """The sun: unit direction of travel, irradiance per channel on a surface facing it."""
    for k, example in (("direction", "[0.3, -1.0, 0.2] (the way the light travels)"), ("irradiance", "3.0")):
        if k not in raw:
            read.fail(f"{key}.{k}", "missing", f"add {key}.{k} = {example}")
    axis = read.vec3(f"{key}.direction", raw["direction"])
    norm = float(np.linalg.norm(axis))
    if not norm > 0.0:
        read.fail(f"{key}.direction", "is zero", "give the direction the light travels, e.g. [0.3, -1.0, 0.2]")
    return Light(np.zeros(3), power(read, f"{key}.irradiance", read.rgb(f"{key}.irradiance", raw["irradiance"])),
                 CODE, axis / norm)


def describe(light) -> str:
    return f"{NAME}, travelling along {light.axis.round(6).tolist()}, irradiance {light.intensity.tolist()}"


def irradiance(lights, index, to_points, dist):
    """E per channel (N, 3), whatever the distance."""
    return np.broadcast_to(lights.intensity[index], (len(dist), 3))


@njit
def sample(position, axis, cone, li, px, py, pz):
    """(-axis, inf, 1): toward the light, from infinitely far."""
    return -axis[li, 0], -axis[li, 1], -axis[li, 2], math.inf, 1.0
