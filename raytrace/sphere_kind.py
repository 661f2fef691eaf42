"""The exact sphere as a boundary kind: ray intersection in float64 beside Embree's triangles.

A shape `primitive = "sphere"` with `exact = true` (scene/format.py) keeps its mesh of `segments` in
the scene's triangle arrays (its rows carry its shape index, reflectance and corner normals), but
Embree never sees those rows: accel.py intersects the sphere itself with `sphere_roots` and reports a
hit on it as its first row (`Accelerator.hit_normals` gives the exact normal there).

Roots of |f + t d|^2 = r^2, f = o - c (Press et al., Numerical Recipes 5.6; Ericson, Real-Time
Collision Detection 5.3.2): with b = f·d, a = d·d and h = f - (b / a) d the offset of the line from
the centre, the quarter discriminant is b^2 - a (f·f - r^2) = a (r - |h|)(r + |h|), free of the
cancellation of the textbook form for grazing and far rays; q = -(b + sign(b) sqrt(disc)) gives the
roots q / a and (f·f - r^2) / q, neither formed as a difference of nearly equal numbers. Everything
is divided first by s = max(|f|_inf, r), so neither huge (1e200) nor tiny (1e-200) scenes overflow
or underflow; the roots are then s times those of the scaled problem.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import njit

# the stable forms above must be evaluated as written: no reassociation, no approximate reciprocals
exact_njit = njit(fastmath=False)


@exact_njit
def sphere_roots(o, d, c, r):
    """The two roots (t0 <= t1) of |o + t d - c| = r in float64, or (inf, inf) where the line misses
    the sphere (or d = 0)."""
    f0, f1, f2 = o[0] - c[0], o[1] - c[1], o[2] - c[2]
    s = max(abs(f0), abs(f1), abs(f2), r)
    if not s > 0.0 or not math.isfinite(s):
        return np.inf, np.inf
    f0, f1, f2, rr = f0 / s, f1 / s, f2 / s, r / s
    a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    if not a > 0.0:
        return np.inf, np.inf
    b = f0 * d[0] + f1 * d[1] + f2 * d[2]
    k = b / a
    h0, h1, h2 = f0 - k * d[0], f1 - k * d[1], f2 - k * d[2]
    h = math.sqrt(h0 * h0 + h1 * h1 + h2 * h2)
    if h > rr:
        return np.inf, np.inf
    disc = a * (rr - h) * (rr + h)
    q = -(b + math.copysign(math.sqrt(disc), b))
    nf = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    c0 = (nf - rr) * (nf + rr)
    t0 = q / a
    t1 = c0 / q if q != 0.0 else -t0  # q = 0: b = 0 and disc = 0, the ray grazes at t = 0
    if t0 > t1:
        t0, t1 = t1, t0
    return t0 * s, t1 * s


@exact_njit
def nearest_sphere_hits(origins, dirs, spheres, rows, t, prim):
    """Where a ray meets a sphere (centres spheres[:, :3], radii spheres[:, 3]) at 0 < t' < t[i],
    t[i] = t' and prim[i] = rows[sphere] (spheres whose row is -1 are skipped): the nearest hit wins."""
    for i in range(origins.shape[0]):
        for k in range(spheres.shape[0]):
            if rows[k] < 0:
                continue
            t0, t1 = sphere_roots(origins[i], dirs[i], spheres[k, :3], spheres[k, 3])
            hit = t0 if t0 > 0.0 else t1
            if hit > 0.0 and hit < t[i]:
                t[i] = hit
                prim[i] = rows[k]


@exact_njit
def sphere_blocks(origins, dirs, tmax, spheres, rows, occ):
    """occ[i] |= a sphere (rows[k] >= 0) meets the ray at 0 < t < tmax[i]."""
    for i in range(origins.shape[0]):
        if occ[i]:
            continue
        for k in range(spheres.shape[0]):
            if rows[k] < 0:
                continue
            t0, t1 = sphere_roots(origins[i], dirs[i], spheres[k, :3], spheres[k, 3])
            if (0.0 < t0 < tmax[i]) or (0.0 < t1 < tmax[i]):
                occ[i] = True
                break
