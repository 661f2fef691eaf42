"""Volumetric shadows of a directional light refracted into a convex shape: the pieces of camera
segments inside the shape that a refracted beam reaches past every occluder.

Face f's beam (fresnel.refracted_beams: the light refracted through f, travelling along -u inside)
reaches a point p inside along a straight leg from its entry point e(p) = p + s(p) u on f's plane,
s(p) = (c - n.p) / (n.u), and e(p) is lit from outside along the light's own direction. On a camera
segment p(x) = o + x w inside the shape, both legs are exact lit-interval problems of
shadows/frusta.py, with no sampling:
- outside: e(x) = e(0) + x v, v = w - (n.w / n.u) u, is a segment of f's plane. Its lit pieces
  under the light, past every blocker but the shape itself (convex: its other faces lie behind f),
  map back to x through |v|. Where the entry point hardly moves (|v| ell below DEGENERATE of the
  scene's size: w along u) the whole segment takes the answer at its midpoint.
- inside: the leg runs inside the convex shape, so only what lies inside it can stop the light
  there: the blockers clipped to the shape's planes (fans of the clipped polygons), under a
  directional light travelling along -u.
The segment is lit by the beam where both legs are lit (`_intersect`). Whether the beam reaches a
point at all (its path back leaving through f) is the integrator's business (the `only` face of
media/convex_directional.py and media/slab.py). Not handled: an occluder lying in f's own plane
(touching the face from outside), for which the outside leg's side is a matter of rounding.
"""
from __future__ import annotations

import numpy as np

from ..geometry.vectors import perpendicular
from ..jit import njit
from ..methods import Segments
from .frusta import STATS_NAMES, lit_pieces, sun_bins

DEGENERATE = 1e-9  # x the scene's size: an entry segment shorter than this is one point


def clip_to_solid(tris: np.ndarray, planes: np.ndarray) -> np.ndarray:
    """The parts of the triangles `tris` (T, 3, 3) inside the convex solid n.x <= c of `planes`
    (P, 4: outward unit normal, offset), as triangles (T', 3, 3): those wholly inside as they are,
    those crossing its boundary clipped plane by plane (Sutherland-Hodgman) and fanned."""
    if not len(tris) or not len(planes):
        return np.zeros((0, 3, 3))
    d = np.einsum("tvk,pk->tvp", tris, planes[:, :3]) - planes[:, 3]
    outside = np.any(np.all(d > 0.0, axis=1), axis=1)
    inside = np.all(d <= 0.0, axis=(1, 2))
    out = [tris[inside]]
    for tri in tris[~outside & ~inside]:
        poly = list(tri)
        for n, c in zip(planes[:, :3], planes[:, 3]):
            clipped = []
            for i, a in enumerate(poly):
                b = poly[(i + 1) % len(poly)]
                da, db = float(n @ a) - c, float(n @ b) - c
                if da <= 0.0:
                    clipped.append(a)
                if (da < 0.0 < db) or (db < 0.0 < da):
                    clipped.append(a + (da / (da - db)) * (b - a))
            poly = clipped
            if len(poly) < 3:
                break
        if len(poly) >= 3:
            out.append(np.array([[poly[0], poly[i], poly[i + 1]] for i in range(1, len(poly) - 1)]))
    return np.concatenate(out).reshape(-1, 3, 3)


def lit_pieces_of_beam(prep, sid: int, planes: np.ndarray, blockers, li: int, face: int, toward: np.ndarray,
                       points: np.ndarray, w: np.ndarray, ell: np.ndarray):
    """(segment, x0, x1) of the pieces of the segments points + x w, x in [0, ell], inside convex
    shape `sid` (face planes `planes`) that face `face`'s beam of directional light `li` (minus its
    direction inside: `toward`) reaches past the `blockers` (a mask over prep.accel.triangles, None:
    all), by segment and x; the frusta are built once per shape, light and beam (prep.memo)."""
    accel = prep.accel
    others = prep.shape_ids != sid if blockers is None else blockers & (prep.shape_ids != sid)
    stats = np.zeros(len(STATS_NAMES))
    # outside: the entry points' segment on the face's plane, under the light itself
    outside = prep.memo(("beam outside", sid, li), lambda: sun_bins(accel.triangles[others], prep.lights.axis[li],
                                                                    accel.epsilon, accel.scale))
    normal, offset = planes[face, :3], planes[face, 3]
    q = float(normal @ toward)
    e0 = points + ((offset - points @ normal) / q)[:, None] * toward
    v = w - ((w @ normal) / q)[:, None] * toward
    speed = np.linalg.norm(v, axis=1)
    moves = speed * ell > DEGENERATE * accel.scale
    dirs = np.where(moves[:, None], v / np.where(moves, speed, 1.0)[:, None], perpendicular(normal))
    start = np.where(moves[:, None], e0, e0 + 0.5 * ell[:, None] * v - 0.5 * DEGENERATE * accel.scale * dirs)
    length = np.where(moves, speed * ell, DEGENERATE * accel.scale)
    so, u0, u1 = lit_pieces(_segments(start, dirs, length, accel.scale), [outside], accel.scale, stats)
    point = ~moves[so]  # one point: lit over the whole segment if its midpoint is
    mid = 0.5 * DEGENERATE * accel.scale
    keep = ~point | ((u0 <= mid) & (mid <= u1))
    so, u0, u1 = so[keep], u0[keep], u1[keep]
    speed_o = np.where(moves[so], speed[so], 1.0)
    x0 = np.where(moves[so], u0 / speed_o, 0.0)
    x1 = np.where(moves[so], np.minimum(u1 / speed_o, ell[so]), ell[so])
    # inside: the leg from the entry point, past what lies inside the shape
    inside = prep.memo(("beam inside", sid, li, face), lambda: _inside_bins(prep, sid, planes, others, toward))
    if inside is None:
        return so, x0, x1
    si, y0, y1 = lit_pieces(_segments(points, w, ell, accel.scale), [inside], accel.scale, stats)
    return _intersect(so, x0, x1, si, y0, y1)


def _inside_bins(prep, sid, planes, others, toward):
    """The frusta of the blockers inside shape sid under the beam travelling along -toward, or None."""
    inner = blockers_inside(prep, sid, planes, others)
    if not len(inner):
        return None
    return sun_bins(inner, -toward, prep.accel.epsilon, prep.accel.scale)


def blockers_inside(prep, sid, planes, others):
    """The parts inside convex shape sid (face planes `planes`) of the triangles `others` (a mask over
    prep.accel.triangles), as triangles (U, 3, 3): `clip_to_solid` of those near its bounding box."""
    own = prep.accel.triangles[prep.shape_ids == sid].reshape(-1, 3)
    lo, hi = own.min(axis=0), own.max(axis=0)
    tris = prep.accel.triangles[others]
    near = np.all((tris.max(axis=1) >= lo) & (tris.min(axis=1) <= hi), axis=1)
    return clip_to_solid(tris[near], planes)


def _segments(origins, dirs, length, scale):
    n = len(origins)
    zero = np.zeros(n, np.int64)
    return Segments(np.ascontiguousarray(origins), np.ascontiguousarray(dirs), np.ascontiguousarray(length), zero,
                    np.arange(n), np.zeros(n), np.zeros(n, np.uint64), zero, 0, scale)


@njit
def _intersect(sa, a0, a1, sb, b0, b1):
    """The intersection of two unions of intervals per segment, each list ordered by segment and x."""
    cap = sa.shape[0] + sb.shape[0]
    src, x0, x1 = np.empty(cap, np.int64), np.empty(cap), np.empty(cap)
    i = j = m = 0
    while i < sa.shape[0] and j < sb.shape[0]:
        if sa[i] < sb[j]:
            i += 1
        elif sb[j] < sa[i]:
            j += 1
        else:
            lo, hi = max(a0[i], b0[j]), min(a1[i], b1[j])
            if hi > lo:
                src[m], x0[m], x1[m] = sa[i], lo, hi
                m += 1
            if a1[i] < b1[j]:
                i += 1
            else:
                j += 1
    return src[:m].copy(), x0[:m].copy(), x1[:m].copy()
