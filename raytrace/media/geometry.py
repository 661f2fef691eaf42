"""Ray-light geometry shared by every air-light method (METHODS.md §1).

For a ray o + x w (|w| = 1, camera at x = 0) and a light p: x_h = (p - o)·w is the light's
projection coordinate, h = |(p - o) x w| its distance to the ray line (from the cross product, which
keeps full relative precision when the light is near the line), d_a = |p - o|. h is clamped to
H_MIN_REL times the larger of d_a and the scene's size (`RayBatch.scale`): the light is treated as
a sphere of that radius, so that a ray through a light, even a camera placed on a light, gives a
large but finite air-light (a true point light on the ray gives an infinite one).
"""
import math

import numpy as np

from ..jit import njit

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
def ray_light_table(origins, dirs, lpos, scale):
    """(x_h, h, d_a) of every light for every ray, each (N, L); `scale`: the scene's size."""
    n, nl = origins.shape[0], lpos.shape[0]
    xh, h, da = np.empty((n, nl)), np.empty((n, nl)), np.empty((n, nl))
    for r in range(n):
        for li in range(nl):
            xh[r, li], h[r, li], da[r, li] = ray_light(origins[r, 0], origins[r, 1], origins[r, 2], dirs[r, 0],
                                                       dirs[r, 1], dirs[r, 2], lpos[li, 0], lpos[li, 1], lpos[li, 2],
                                                       scale)
    return xh, h, da


def by_channel(batch, medium, lpos, lint, evaluate):
    """Air-light (N, 3) of a ray batch summed over lights. `evaluate(xh, h, da, tmax, kt, ks)` returns
    the unit-intensity air-light (N, L) for one channel's coefficients; channels with equal
    (kt, ks) share one call, channels that do not scatter are 0."""
    xh, h, da = ray_light_table(batch.origins, batch.dirs, lpos, batch.scale)
    out = np.zeros((len(batch.origins), 3))
    done = {}
    for c in range(3):
        key = (float(medium.sigma_t[c]), float(medium.sigma_s[c]))
        if key[1] == 0.0:
            continue
        if key not in done:
            done[key] = evaluate(xh, h, da, batch.tmax, *key)
        out[:, c] = done[key] @ lint[:, c]
    return out
