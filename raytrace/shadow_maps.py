"""Depth cube maps of the lights: a cheap pre-classification of the lit-interval search's samples.

For each light, the distance to the first surface is traced (Embree) in the directions of the
corners of a cube map's texels, R x R texels per face; each texel keeps the least and the largest
of its corners' depths (float32, rounded outwards). A visibility sample at distance r in a
direction whose texel's four corners all see farther than r (by a relative MARGIN) is taken as lit,
one whose four corners all see nearer as shadowed; any other sample, and every sample on a surface,
gets an exact shadow ray. The texel diagonal is kept below the search's angular spacing, so the map
adds nothing to what the search can miss (occluders or gaps narrower than the spacing, seen from the
light); where that would need more than MAX_RES texels per face the map is not used.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import njit

MAX_RES = 1024
MARGIN = 1e-3  # relative depth margin: a planar surface's depth between texel corners deviates by ~texel^2


def resolution(spacing: float) -> int:
    """Texels per face edge whose diagonal (2 sqrt(2) / R radians at most) is below `spacing`; 0 if
    that exceeds MAX_RES."""
    r = max(16, math.ceil(2.0 * math.sqrt(2.0) / spacing))
    return r if r <= MAX_RES else 0


def corner_directions(res: int) -> np.ndarray:
    """Unit directions (6, R+1, R+1, 3) of the texel corners; face 2a + (0 for +, 1 for -) looks
    along axis a, its grid runs along axes a+1 and a+2 (mod 3)."""
    t = np.linspace(-1.0, 1.0, res + 1)
    u, v = np.meshgrid(t, t, indexing="ij")
    out = np.empty((6, res + 1, res + 1, 3))
    for a in range(3):
        for side, sign in enumerate((1.0, -1.0)):
            f = out[2 * a + side]
            f[..., a] = sign
            f[..., (a + 1) % 3] = u
            f[..., (a + 2) % 3] = v
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def build(accel, lights, spacing: float) -> np.ndarray:
    """Per light and texel the least and the largest depth of its four corners, (L, 6, R, R, 2)
    float32 (inf where nothing is hit; the least rounded down, the largest up), or an empty
    (0, 6, 1, 1, 2) array when the spacing is too fine for MAX_RES or the scene has no geometry."""
    res = resolution(spacing)
    if not res or not len(accel.triangles):
        return np.zeros((0, 6, 1, 1, 2), np.float32)
    dirs = corner_directions(res).reshape(-1, 3)
    maps = np.empty((len(lights), 6, res, res, 2), np.float32)
    for li, p in enumerate(lights.position):
        t, _ = accel.first_hit(np.broadcast_to(p, dirs.shape), dirs, threads=2)
        t = t.reshape(6, res + 1, res + 1)
        corners = np.stack([t[:, :-1, :-1], t[:, 1:, :-1], t[:, :-1, 1:], t[:, 1:, 1:]])
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        maps[li, ..., 0] = np.nextafter(lo.astype(np.float32), np.float32(0.0))
        maps[li, ..., 1] = np.nextafter(hi.astype(np.float32), np.float32(np.inf))
    return maps


@njit
def classify(maps, li, dx, dy, dz, r):
    """1 (lit), 0 (shadowed) or -1 (undecided: trace a ray) for the point at distance r (may be inf)
    in the unit direction (dx, dy, dz) from light li."""
    if maps.shape[0] == 0:
        return -1
    ax, ay, az = abs(dx), abs(dy), abs(dz)
    if ax >= ay and ax >= az:
        a, m, u, v = 0, dx, dy / ax, dz / ax
    elif ay >= az:
        a, m, u, v = 1, dy, dz / ay, dx / ay
    else:
        a, m, u, v = 2, dz, dx / az, dy / az
    face = 2 * a + (0 if m > 0.0 else 1)
    res = maps.shape[2]
    i = min(max(int(0.5 * (u + 1.0) * res), 0), res - 1)
    j = min(max(int(0.5 * (v + 1.0) * res), 0), res - 1)
    lo, hi = maps[li, face, i, j, 0], maps[li, face, i, j, 1]
    if r == math.inf:
        return 1 if lo == math.inf else (0 if hi < math.inf else -1)
    if r * (1.0 + MARGIN) < lo:
        return 1
    if r > hi * (1.0 + MARGIN):
        return 0
    return -1
