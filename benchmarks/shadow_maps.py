"""Depth cube maps of the lights: a cheap pre-classification of the lit-interval search's samples.

For each light, the distance to the first surface is traced (Embree) in the directions of the
corners of a cube map's texels, R x R texels per face; each texel keeps the least and the largest
of its corners' depths (float32, rounded outwards), and coarser levels keep the least and largest
over 2 x 2 texels. A visibility sample at distance r in a direction whose texel's corners all see
farther than r (by a relative MARGIN) is taken as lit, one whose corners all see nearer as
shadowed; any other sample, and every sample on a surface, gets an exact shadow ray. A run of
samples whose directions share one coarse texel (a great-circle arc in a convex texel of a cube
face) is decided at once when that texel's bounds decide its whole range of distances. The texel diagonal is kept below the search's angular spacing, so the map
adds nothing to what the search can miss (occluders or gaps narrower than the spacing, seen from the
light); where that would need more than MAX_RES texels per face the map is not used.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raytrace.jit import njit

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


@dataclass(frozen=True)
class ShadowMaps:
    """The lights' depth pyramids: `table` (N, 2) float32 holds (least, largest) corner depth per
    texel of every level, light and face; level l has `sizes[l]` texels per face edge (level 0 the
    finest, each coarser texel the union of 2 x 2 finer ones) and starts at texel `offsets[l]`;
    texel (li, face, i, j) of level l is at offsets[l] + ((li * 6 + face) * sizes[l] + i) * sizes[l] + j."""
    table: np.ndarray
    sizes: np.ndarray
    offsets: np.ndarray

    @classmethod
    def empty(cls) -> "ShadowMaps":
        return cls(np.zeros((0, 2), np.float32), np.zeros(0, np.int64), np.zeros(1, np.int64))


def build(accel, lights, spacing: float) -> ShadowMaps:
    """The depth pyramids of every light (inf where nothing is hit; least depths rounded down,
    largest up), or empty maps when the spacing is too fine for MAX_RES or there is no geometry."""
    res = resolution(spacing)
    if not res or not len(accel.triangles) or not len(lights):
        return ShadowMaps.empty()
    dirs = corner_directions(res).reshape(-1, 3)
    lo = np.empty((len(lights), 6, res, res), np.float32)
    hi = np.empty_like(lo)
    for li, p in enumerate(lights.position):
        t, _ = accel.first_hit(p + accel.epsilon * dirs, dirs, threads=2)  # as the search's shadow rays
        t = (t + accel.epsilon).reshape(6, res + 1, res + 1)
        corners = np.stack([t[:, :-1, :-1], t[:, 1:, :-1], t[:, :-1, 1:], t[:, 1:, 1:]])
        lo[li] = np.nextafter(corners.min(axis=0).astype(np.float32), np.float32(0.0))
        hi[li] = np.nextafter(corners.max(axis=0).astype(np.float32), np.float32(np.inf))
    levels = [(lo, hi)]
    while levels[-1][0].shape[-1] > 1:
        lo, hi = levels[-1]
        n = lo.shape[-1]
        pad = ((0, 0), (0, 0), (0, n % 2), (0, n % 2))
        lo, hi = np.pad(lo, pad, mode="edge"), np.pad(hi, pad, mode="edge")
        m = lo.shape[-1] // 2
        levels.append((lo.reshape(len(lights), 6, m, 2, m, 2).min(axis=(3, 5)),
                       hi.reshape(len(lights), 6, m, 2, m, 2).max(axis=(3, 5))))
    table = np.concatenate([np.stack([a.ravel(), b.ravel()], axis=1) for a, b in levels])
    sizes = np.array([a.shape[-1] for a, _ in levels], np.int64)
    offsets = np.concatenate([[0], np.cumsum([a.size for a, _ in levels])]).astype(np.int64)
    return ShadowMaps(table, sizes, offsets)


@njit
def face_texel(sizes, dx, dy, dz):
    """(face, i, j) of the finest texel holding the direction (dx, dy, dz)."""
    ax, ay, az = abs(dx), abs(dy), abs(dz)
    if ax >= ay and ax >= az:
        a, m, u, v = 0, dx, dy / ax, dz / ax
    elif ay >= az:
        a, m, u, v = 1, dy, dz / ay, dx / ay
    else:
        a, m, u, v = 2, dz, dx / az, dy / az
    res = sizes[0]
    i = min(max(int(0.5 * (u + 1.0) * res), 0), res - 1)
    j = min(max(int(0.5 * (v + 1.0) * res), 0), res - 1)
    return 2 * a + (0 if m > 0.0 else 1), i, j


@njit
def verdict(table, sizes, offsets, level, li, face, i, j, r_min, r_max):
    """1 (lit), 0 (shadowed) or -1 (undecided) for points at distances within [r_min, r_max] (r_max
    may be inf) in directions inside the level's texel holding finest texel (i, j)."""
    n = sizes[level]
    row = table[offsets[level] + ((li * 6 + face) * n + (i >> level)) * n + (j >> level)]
    lo, hi = row[0], row[1]
    if r_max == math.inf:
        return 1 if lo == math.inf else (0 if hi < math.inf and r_min > hi * (1.0 + MARGIN) else -1)
    if r_max * (1.0 + MARGIN) < lo:
        return 1
    if r_min > hi * (1.0 + MARGIN):
        return 0
    return -1
