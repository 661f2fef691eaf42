"""Segment-light geometry and the eq. 4 integrand shared by the air-light methods (METHODS.md §1).

For a segment o + x w (|w| = 1, x = 0 at the segment's own start) and a light p: x_h = (p - o)·w is
the light's projection coordinate, h = |(p - o) x w| its distance to the ray line (from the cross
product, which keeps full relative precision when the light is near the line), d_a = |p - o|. h is
clamped to H_MIN_REL times the larger of d_a and the scene's size (`Segments.scale`): the light is
treated as a sphere of that radius, so that a ray through a light, even a camera placed on a light,
gives a large but finite air-light (a true point light on the ray gives an infinite one).
"""
import math

import numpy as np

from ..jit import njit
from ..media.phase import phase_value

H_MIN_REL = 1e-9


@njit
def ray_light(ox, oy, oz, wx, wy, wz, px, py, pz, scale):
    """(x_h, h, d_a) of the light (px, py, pz) relative to the ray; `scale`: the scene's size."""
    rx, ry, rz = px - ox, py - oy, pz - oz
    xh = rx * wx + ry * wy + rz * wz
    cx = ry * wz - rz * wy
    cy = rz * wx - rx * wz
    cz = rx * wy - ry * wx
    h = math.sqrt(cx * cx + cy * cy + cz * cz)
    da = math.sqrt(rx * rx + ry * ry + rz * rz)
    h = max(h, H_MIN_REL * max(da, scale), 1e-300)
    return xh, h, da


@njit
def segment_light_table(origins, dirs, lpos, light, scale):
    """(x_h, h, d_a) of every segment's light from the segment's start, each (S,)."""
    n = origins.shape[0]
    xh, h, da = np.empty(n), np.empty(n), np.empty(n)
    for s in range(n):
        li = light[s]
        xh[s], h[s], da[s] = ray_light(origins[s, 0], origins[s, 1], origins[s, 2], dirs[s, 0], dirs[s, 1],
                                       dirs[s, 2], lpos[li, 0], lpos[li, 1], lpos[li, 2], scale)
    return xh, h, da


def segment_geometry(segs, lights):
    """(x_h, h, d_a) arrays (S,) of a `Segments` batch and its lights."""
    return segment_light_table(segs.origins, segs.dirs, lights.position, segs.light, segs.scale)


@njit
def eq4_integrand(x, xh, h, kt, ks, code, g):
    """The air-light integrand of eq. 4 for a unit-intensity light (x_h, h) at distance x along the
    segment: ks Phi(-(x - x_h) / d) exp(-kt (x + d)) / d^2, d = sqrt(h^2 + (x - x_h)^2). x + d is the
    whole optical path light -> x -> segment start, so nothing overflows for lights far behind."""
    dx = x - xh
    d2 = max(h * h + dx * dx, 1e-250)  # h is >= 1e-300: keep 1/d^2 finite when h*h underflows
    d = math.sqrt(d2)
    return ks * math.exp(-kt * (x + d)) * phase_value(code, g, -dx / d) / d2


def by_channel(segs, medium, lights, evaluate):
    """Air-light (S, 3) of a segment batch. `evaluate(xh, h, da, length, kt, ks)` returns the
    unit-intensity air-light (S,) for one channel's coefficients; channels with equal (kt, ks) share
    one call, channels that do not scatter are 0."""
    xh, h, da = segment_geometry(segs, lights)
    out = np.zeros((len(segs), 3))
    done = {}
    for c in range(3):
        key = (float(medium.sigma_t[c]), float(medium.sigma_s[c]))
        if key[1] == 0.0:
            continue
        if key not in done:
            done[key] = evaluate(xh, h, da, segs.length, *key)
        _scale_into(out, c, done[key], lights.intensity, segs.light)
    return out


@njit
def _scale_into(out, c, unit, intensity, light):
    """out[s, c] = unit[s] * intensity[light[s], c]."""
    for s in range(unit.shape[0]):
        out[s, c] = unit[s] * intensity[light[s], c]
