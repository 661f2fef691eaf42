"""Directional light (the sun) into a refractive shape that is not convex: each face's beam over its exact lit pieces.

The light (unit direction of travel `axis`) meets each triangle F of a closed mesh whose plane faces it (its
normal turned toward the light: either orientation) and, refracted there, travels inside along a constant
direction d_F (interiors/fresnel.py `refracted_beams`: the beam, its irradiance T cos_i / cos_t). A point X
inside is lit by F's beam where its path back, X + s u (u = -d_F, s > 0), leaves the shape through F: it meets
F's plane at P = X + s_F u inside the triangle, no other triangle on the way (the inside leg), and the light's
leg from P back toward the source, P - r axis (r > 0), meets no triangle (the outside leg). Every triangle is
taken in either orientation; a face whose outside looks into the shape gives a path that leaves before it, which
the inside leg rejects.

On a camera segment X(t) = o + t w, t in [0, T], each condition is linear in t: s_F(t) = alpha + beta t > 0;
P(t) = o + alpha u + t (w + beta u) moves along a line of F's plane, so each edge test of F is a linear
inequality; another triangle G blocks the inside leg where its plane's crossing v_G(t) (linear) lies in
(0, s_F(t)) and Q(t) = X(t) + v_G(t) u (linear) in G, and blocks the outside leg where P(t)'s crossing
r_G(t) > 0 and R(t) = P(t) - r_G(t) axis lies in G. Each blocker's set is an intersection of half-lines, one
interval; F's lit pieces are its own interval less their union (`beam_pieces`). The pieces' ends are computed
in doubles, not bounded.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit


@njit
def _clip(lo, hi, a, b):
    """[lo, hi] cut to {t : a + b t >= 0}."""
    if b > 0.0:
        return max(lo, -a / b), hi
    if b < 0.0:
        return lo, min(hi, -a / b)
    return (lo, hi) if a >= 0.0 else (lo, -math.inf)


def edge_planes(tris):
    """(T, 3, 4) per triangle and edge (a, b): e = n x (b - a), n the normal of the vertex order (the edge's inward
    normal in the triangle's plane, whichever the order), and its offset o = e . a: a point p of the plane lies in
    the triangle where all three rows give e . p - o >= 0 ((b - a) x (p - a) . n >= 0)."""
    tris = np.asarray(tris, dtype=np.float64)
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    out = np.empty((len(tris), 3, 4))
    for k in range(3):
        a, b = tris[:, k], tris[:, (k + 1) % 3]
        e = np.cross(n, b - a)  # (b - a) x (p - a) . n = (p - a) . (n x (b - a))
        out[:, k, :3], out[:, k, 3] = e, np.einsum("ij,ij->i", e, a)
    return np.ascontiguousarray(out)


@njit
def _in_triangle(lo, hi, edges, p0, p1):
    """[lo, hi] cut to the t where p0 + t p1 lies in the triangle of `edges` (3, 4: `edge_planes`' rows; p0, p1
    on its plane)."""
    for k in range(3):
        e = edges[k]
        lo, hi = _clip(lo, hi, e[0] * p0[0] + e[1] * p0[1] + e[2] * p0[2] - e[3],
                       e[0] * p1[0] + e[1] * p1[1] + e[2] * p1[2])
        if not hi > lo:
            break
    return lo, hi


@njit
def _crossing(normal, offset, p0, p1, d):
    """(c0, c1): the parameter c0 + c1 t where p0 + t p1 + c d meets the plane normal . x = offset (d not parallel)."""
    q = normal[0] * d[0] + normal[1] * d[1] + normal[2] * d[2]
    return ((offset - (normal[0] * p0[0] + normal[1] * p0[1] + normal[2] * p0[2])) / q,
            -(normal[0] * p1[0] + normal[1] * p1[1] + normal[2] * p1[2]) / q)


@njit
def _blocked(edges, normal, offset, p0, p1, d, lo, hi, s0, s1, q0, q1):
    """The interval of t in [lo, hi] where the leg p0 + t p1 + c d, 0 < c < s0 + s1 t (s0 = inf: unbounded),
    meets the triangle of `edges` (plane normal . x = offset); empty (hi <= lo) where the leg runs along its plane.
    q0, q1 (3,): scratch."""
    q = normal[0] * d[0] + normal[1] * d[1] + normal[2] * d[2]
    if q == 0.0:
        return lo, -math.inf
    c0, c1 = _crossing(normal, offset, p0, p1, d)
    lo, hi = _clip(lo, hi, c0, c1)
    if s0 < math.inf:
        lo, hi = _clip(lo, hi, s0 - c0, s1 - c1)
    if not hi > lo:
        return lo, hi
    for k in range(3):
        q0[k], q1[k] = p0[k] + c0 * d[k], p1[k] + c1 * d[k]
    return _in_triangle(lo, hi, edges, q0, q1)


@njit
def _subtract(lo, hi, cuts, m, seg, src, x0, x1, k):
    """Write [lo, hi] less the union of the intervals cuts[:m] as pieces of segment seg into src, x0, x1 from
    k on; returns the new count (or -1 where the arrays are full)."""
    order = np.argsort(cuts[:m, 0])
    t = lo
    for i in order:
        a, b = cuts[i, 0], cuts[i, 1]
        if a > t:
            if k >= src.shape[0]:
                return -1
            src[k], x0[k], x1[k] = seg, t, min(a, hi)
            k += 1
        t = max(t, b)
        if t >= hi:
            return k
    if hi > t:
        if k >= src.shape[0]:
            return -1
        src[k], x0[k], x1[k] = seg, t, hi
        k += 1
    return k


@njit
def _box(out, a0, a1, b0, b1, lo, hi, reach):
    """out (6,) = the box (min, max) of the points a0 + t a1 and b0 + t b1 at t = lo and hi and of the same moved
    by `reach`."""
    for j in range(3):
        v = (a0[j] + lo * a1[j], a0[j] + hi * a1[j], b0[j] + lo * b1[j], b0[j] + hi * b1[j])
        out[j], out[3 + j] = min(v), max(v)
        out[j] = min(out[j], out[j] + reach[j])
        out[3 + j] = max(out[3 + j], out[3 + j] + reach[j])


@njit
def _meets(box, tbox):
    return (tbox[0] <= box[3] and box[0] <= tbox[3] and tbox[1] <= box[4] and box[1] <= tbox[4]
            and tbox[2] <= box[5] and box[2] <= tbox[5])


@njit
def beam_pieces(edges, planes, boxes, size, faces, towards, axis, origins, dirs, lengths, beam, src, x0, x1):
    """The pieces (beam: index into faces, src: segment, x0, x1; by beam, then segment and t) of the segments
    origins + t dirs, t in [0, lengths], that each face's beam lights (module docstring; towards (B, 3): minus each
    beam's direction inside, unit; edges: `edge_planes`; planes (T, 4): the triangles' unit normals and offsets,
    any orientation; boxes (T, 6): their bounding boxes, size: the diagonal of the shape's). A blocker is tested
    only where its box meets the box of the legs: the inside legs' ends X and P at the interval's ends, the outside
    legs' from P over `size` toward the light (beyond, nothing of the shape). Returns their number, or -1 where
    beam, src, x0, x1 are too short."""
    back = -axis
    cuts = np.empty((2 * planes.shape[0], 2))
    p0, p1, q0, q1 = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    inner, outer, still, far = np.empty(6), np.empty(6), np.zeros(3), size * back
    k = 0
    for i in range(faces.shape[0]):
        f, toward = faces[i], towards[i]
        nf, cf = planes[f, :3], planes[f, 3]
        for s in range(origins.shape[0]):
            o, w = origins[s], dirs[s]
            alpha, beta = _crossing(nf, cf, o, w, toward)
            lo, hi = _clip(0.0, lengths[s], alpha, beta)
            if not hi > lo:
                continue
            for j in range(3):
                p0[j], p1[j] = o[j] + alpha * toward[j], w[j] + beta * toward[j]
            lo, hi = _in_triangle(lo, hi, edges[f], p0, p1)
            if not hi > lo:
                continue
            _box(inner, o, w, p0, p1, lo, hi, still)
            _box(outer, p0, p1, p0, p1, lo, hi, far)
            m = 0
            for g in range(planes.shape[0]):
                if g == f:
                    continue
                ng, cg = planes[g, :3], planes[g, 3]
                if _meets(inner, boxes[g]):
                    a, b = _blocked(edges[g], ng, cg, o, w, toward, lo, hi, alpha, beta, q0, q1)
                    if b > a:
                        cuts[m, 0], cuts[m, 1] = a, b
                        m += 1
                if _meets(outer, boxes[g]):
                    a, b = _blocked(edges[g], ng, cg, p0, p1, back, lo, hi, math.inf, 0.0, q0, q1)
                    if b > a:
                        cuts[m, 0], cuts[m, 1] = a, b
                        m += 1
                if m and cuts[m - 1, 0] <= lo and cuts[m - 1, 1] >= hi:  # blocked whole
                    break
            start = k
            k = _subtract(lo, hi, cuts, m, s, src, x0, x1, k)
            if k < 0:
                return -1
            beam[start:k] = i
    return k


def lit_pieces(tris, planes, faces, towards, axis, origins, dirs, lengths):
    """`beam_pieces` of the triangles tris (T, 3, 3) as arrays (beam, src, x0, x1), ordered by beam, segment and
    t."""
    boxes = np.concatenate([tris.min(axis=1), tris.max(axis=1)], axis=1)
    size = float(np.linalg.norm(boxes[:, 3:].max(axis=0) - boxes[:, :3].min(axis=0)))
    cap = 4 * len(lengths) + 16
    args = (edge_planes(tris), np.ascontiguousarray(planes), np.ascontiguousarray(boxes), size,
            np.ascontiguousarray(faces, dtype=np.int64), np.ascontiguousarray(towards, dtype=np.float64),
            np.ascontiguousarray(axis, dtype=np.float64), np.ascontiguousarray(origins, dtype=np.float64),
            np.ascontiguousarray(dirs, dtype=np.float64), np.ascontiguousarray(lengths, dtype=np.float64))
    while True:
        beam, src, x0, x1 = np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap), np.empty(cap)
        k = beam_pieces(*args, beam, src, x0, x1)
        if k >= 0:
            return beam[:k], src[:k], x0[:k], x1[:k]
        cap *= 4
