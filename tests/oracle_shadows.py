"""Slow, obvious twins of volumetric shadows by axis-aligned boxes (plates are boxes of zero
thickness), written from the geometry alone: nothing here imports the renderer.

A point P is in shadow when the segment from P to a point light (or the ray from P toward a
directional light's sun) meets a box: a slab test. Along a line o + x d the shadow can only start
or stop where P crosses a plane through the light (or parallel to the sun's direction) and one of a
box's 12 edges, or one of its 6 face planes: for axis-aligned boxes each is a linear equation in
x, solved in closed form below. The lit pieces are the sub-intervals between those breaks whose
midpoints see the light. Air-light integrals are scipy `quad`s (tests/oracle.py for point and spot
lights; an exponential height fog with closed-form optical depths for the sun).
"""
from __future__ import annotations

import itertools
import math

import numpy as np
from scipy import integrate

from . import oracle


def _edges(lo, hi):
    """The 12 edges of the box: (axis k along which the edge runs, (i, ci), (j, cj)) with the other
    two coordinates fixed."""
    out = []
    for k in range(3):
        i, j = (k + 1) % 3, (k + 2) % 3
        for ci, cj in itertools.product((lo[i], hi[i]), (lo[j], hi[j])):
            out.append((k, (i, ci), (j, cj)))
    return out


def shadow_breaks(o, d, tmax, light, box, sun=False):
    """Distances x in (0, tmax) where o + x d may enter or leave the box's shadow. `light`: a point
    light's position, or (sun) the direction the light travels."""
    lo, hi = np.asarray(box[0], float), np.asarray(box[1], float)
    L = np.asarray(light, float)
    out = []
    for k, (i, ci), (j, cj) in _edges(lo, hi):
        if sun:  # P - E parallel to the plane spanned by the edge (axis k) and the sun: (P_i - ci) L_j = (P_j - cj) L_i
            a = d[i] * L[j] - d[j] * L[i]
            b = (o[i] - ci) * L[j] - (o[j] - cj) * L[i]
        else:  # P, L and the edge coplanar: (P_i - L_i)(cj - L_j) = (P_j - L_j)(ci - L_i)
            a = d[i] * (cj - L[j]) - d[j] * (ci - L[i])
            b = (o[i] - L[i]) * (cj - L[j]) - (o[j] - L[j]) * (ci - L[i])
        if a != 0.0:
            out.append(-b / a)
    for k in range(3):
        for c in (lo[k], hi[k]):
            if d[k] != 0.0:
                out.append((c - o[k]) / d[k])
    return sorted(x for x in out if 0.0 < x < tmax)


def blocked(p, light, box, sun=False) -> bool:
    """Whether the segment from p to the light (sun: the ray from p against the light's direction)
    meets the box: slab test; a box of zero thickness blocks where the segment crosses its plane
    strictly inside the rectangle."""
    lo, hi = np.asarray(box[0], float), np.asarray(box[1], float)
    L = np.asarray(light, float)
    v = -L if sun else L - p
    smax = math.inf if sun else 1.0
    enter, leave = 0.0, smax
    flat = False
    for k in range(3):
        if v[k] == 0.0:
            if not lo[k] < p[k] < hi[k]:
                return False
            continue
        t1, t2 = (lo[k] - p[k]) / v[k], (hi[k] - p[k]) / v[k]
        enter, leave = max(enter, min(t1, t2)), min(leave, max(t1, t2))
        flat |= lo[k] == hi[k]
    return enter < leave or (flat and enter == leave and 0.0 < enter < smax)


def lit_pieces(o, d, tmax, light, boxes, sun=False):
    """The lit pieces [(a, b)] of o + x d, 0 <= x <= tmax (tmax may be inf), merged."""
    o, d = np.asarray(o, float), np.asarray(d, float)
    breaks = sorted({0.0, tmax, *(x for b in boxes for x in shadow_breaks(o, d, tmax, light, b, sun))})
    out = []
    for a, b in zip(breaks[:-1], breaks[1:]):
        mid = 0.5 * (a + b) if b < math.inf else a + max(a, 1.0)
        if not any(blocked(o + mid * d, light, box, sun) for box in boxes):
            if out and out[-1][1] == a:
                out[-1] = (out[-1][0], b)
            else:
                out.append((a, b))
    return out


def first_hit(o, d, boxes):
    """Distance to the nearest box (a plate: its rectangle) along o + x d, inf if none."""
    best = math.inf
    for lo, hi in boxes:
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        enter, leave = 0.0, math.inf
        ok = True
        for k in range(3):
            if d[k] == 0.0:
                ok &= bool(lo[k] <= o[k] <= hi[k])
                continue
            t1, t2 = (lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]
            enter, leave = max(enter, min(t1, t2)), min(leave, max(t1, t2))
        if ok and enter <= leave and enter > 0.0:
            best = min(best, enter)
    return best


def point_airlight(o, d, tmax, light, intensity, kt, ks, phase, g, boxes, spot=None):
    """Eq. 4 over the lit pieces of [0, tmax] under a point or spot light (oracle.airlight on each
    piece from its own start, times exp(-kt a))."""
    total = 0.0
    for a, b in lit_pieces(o, d, tmax, light, boxes):
        start = np.asarray(o, float) + a * np.asarray(d, float)
        total += math.exp(-kt * a) * oracle.airlight(start, d, b - a, light, intensity, kt, ks, phase, g, spot)
    return total


def fog_depth(p, w, s, h0, H):
    """Closed-form optical depth per unit sigma of the exponential fog exp(-(y - h0) / H) along
    p + t w, 0 <= t <= s (s may be inf)."""
    mu = float(w[1])
    base = math.exp(-(float(p[1]) - h0) / H)
    if mu == 0.0:
        return base * s
    if math.isinf(s):
        return base * H / mu if mu > 0.0 else math.inf
    return base * H / mu * -math.expm1(-s * mu / H)


def sun_airlight(o, d, tmax, travel, irradiance, ka, ks, phase, g, h0, H, boxes):
    """Single scattering of a sun (travelling along `travel`, unit) in the exponential height fog
    over the lit pieces of [0, tmax]: scipy quad of ks rho(x) p(cos) E exp(-kt (tau_cam + tau_sun))."""
    kt = ka + ks
    o, d, travel = np.asarray(o, float), np.asarray(d, float), np.asarray(travel, float)
    mu = -float(travel @ d)  # the light's travel direction against the way back to the camera (-d)

    def f(x):
        p = o + x * d
        tau = fog_depth(o, d, x, h0, H) + fog_depth(p, -travel, math.inf, h0, H)
        return ks * math.exp(-(p[1] - h0) / H) * oracle.phase(phase, g, mu) * irradiance * math.exp(-kt * tau)

    total = 0.0
    for a, b in lit_pieces(o, d, tmax, travel, boxes, sun=True):
        total += integrate.quad(f, a, b, epsabs=0.0, epsrel=1e-12, limit=400)[0]
    return total


def triangles_block(p, light, tris, sun=False) -> bool:
    """Whether the segment from p to the light (sun: the ray from p against the light's direction)
    crosses the interior of one of the triangles (T, 3, 3): Moller-Trumbore in float64, vectorised
    over the triangles."""
    p = np.asarray(p, float)
    v = -np.asarray(light, float) if sun else np.asarray(light, float) - p
    smax = math.inf if sun else 1.0
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    h = np.cross(v, e2)
    a = np.einsum("ij,ij->i", e1, h)
    ok = a != 0.0
    f = 1.0 / np.where(ok, a, 1.0)
    s = p - tris[:, 0]
    u = f * np.einsum("ij,ij->i", s, h)
    q = np.cross(s, e1)
    w = f * (q @ v)
    t = f * np.einsum("ij,ij->i", e2, q)
    return bool(np.any(ok & (u > 0.0) & (w > 0.0) & (u + w < 1.0) & (t > 0.0) & (t < smax)))
