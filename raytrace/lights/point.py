"""The point light: isotropic, radiant intensity I per channel, so the irradiance at distance d,
before the medium's attenuation, is I / d^2 (the paper's eqs. 4 and 5). Its one sample is itself.
"""
from __future__ import annotations

import math

from ..jit import njit
from .light import Light, one_row, power

NAME = "point"
CODE = 0  # Light's default kind
KEYS = frozenset({"type", "position", "intensity"})
rows = one_row  # its own one sample


def position_intensity(read, key, raw):
    """The position and the intensity (W/sr per channel) of a point or spot light's table."""
    for k in ("position", "intensity"):
        if k not in raw:
            read.fail(f"{key}.{k}", "missing", f"add {key}.{k}")
    return read.vec3(f"{key}.position", raw["position"]), power(read, f"{key}.intensity",
                                                                read.rgb(f"{key}.intensity", raw["intensity"]))


def parse(read, key, raw) -> Light:
    return Light(*position_intensity(read, key, raw), CODE)


def at(light) -> str:
    """Where a point or spot light is and its intensity, as `describe` prints them."""
    return f"at {light.position.tolist()}, intensity {light.intensity.tolist()}"


def describe(light) -> str:
    return f"{NAME} {at(light)}"


def irradiance(lights, index, to_points, dist):
    """I / d^2 per channel (N, 3) at distances `dist` (N,)."""
    return lights.intensity[index][None, :] / (dist * dist)[:, None]


@njit
def sample(position, axis, cone, li, px, py, pz):
    """(ux, uy, uz, dist, 1): the unit direction and the distance from p to the light;
    (0, 0, 0, 0, 0) at the light's own position."""
    tx, ty, tz = position[li, 0] - px, position[li, 1] - py, position[li, 2] - pz
    dist = math.sqrt(tx * tx + ty * ty + tz * tz)
    if not dist > 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    return tx / dist, ty / dist, tz / dist, dist, 1.0
