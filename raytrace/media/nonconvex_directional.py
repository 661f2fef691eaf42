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
interval; F's lit pieces are its own interval less their union (`beam_pieces`).

The pieces' ends, bounded (first order in u = 2^-53, every term doubled, as media/slab.py and
media/convex_directional.py do). Each condition above is a half-line {h(t) >= 0} of a linear h = A + B t that is
computed as h^ = A^ + B^ t; where |h^(t) - h(t)| <= e at every t that matters, the true half-line lies between
{h^ >= e} and {h^ >= -e}. Cut every condition both ways (`sign` +1: widened, -1: narrowed): a condition set W
(widened, holds the true set) and N (narrowed, held by it), and the true lit set differs from the computed one
only on F's own W_F less N_F and, inside N_F, on each blocker's W_G less N_G (a point outside all of them has
every condition decided alike); a blocker that only the widened leg boxes meet (the computed one skipped it)
counts its whole W_G. The integral over that difference is at most each such span's length times the beam's
largest integrand on it, ks Phi E exp(-kt (g_min - e_s)) (g = t + s_F linear: g_min at an end; e_s s_F's error)
(`beam_pieces`' spans, interiors/rows.py `_sun_faces`). The errors e, with R = |o| + T + 2 max |vertex| (every
point that matters: X, P and a blocker's Q or R on the triangles, every leg shorter), a triangle's plane (dn, dc)
off its true plane and its edge rows (de, do) relative to their norm (`face_errors`, measured against long
doubles), and the beam's direction du off the true refracted one (interiors/rows.py `_beam_errors`):
- the crossing of a plane (n, c) from a start point off by e_0 along a direction off by du: (dc + sqrt(3) dn R
  + 16u (|c| + R) + e_0 + R du) / |q| times 2 (q = n.d; the plane turned about the origin as measured_plane_errors
  has it, the division's 1 / q: the crossing's own condition): e_s for F's s_F (e_0 = 0: X is the segment's),
  e_v for a blocker on the inside leg (e_0 = 0), e_r on the outside leg (e_0 = e_P, du = 0: the light's axis is
  given);
- a point on a leg, P = X + s_F u, Q = X + v u, R = P - r axis: e_P = e_s + 2 (R du + 16u R), e_Q = e_v + 2 (R du
  + 16u R), e_R = e_r + 2 (e_P + 16u R);
- an edge test at such a point, per unit of its row's norm: the point's error plus 2 (de R + do);
- s_F - v > 0: e_s + e_v.
Where q = 0 the crossing is nowhere (the computed set is empty) or, widened, anywhere. A face within dcos of
grazing the light carries irradiance O(dcos^2) (Fresnel's T ~ cos_i there): left out, second order. A triangle of
zero area blocks nothing.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .phase import phase_value

U = 2.0 ** -53  # unit roundoff of doubles
SQ3 = math.sqrt(3.0)


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
def _in_triangle(lo, hi, edges, p0, p1, sign, err, norms):
    """[lo, hi] cut to the t where p0 + t p1 lies in the triangle of `edges` (3, 4: `edge_planes`' rows; p0, p1
    on its plane); sign +1 / -1: each test widened / narrowed by err times its row's norm (`norms`, 3)."""
    for k in range(3):
        e = edges[k]
        a = e[0] * p0[0] + e[1] * p0[1] + e[2] * p0[2] - e[3]
        if sign != 0:
            a += sign * err * norms[k]
        lo, hi = _clip(lo, hi, a, e[0] * p1[0] + e[1] * p1[1] + e[2] * p1[2])
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
def _blocked(edges, normal, offset, p0, p1, d, lo, hi, s0, s1, q0, q1, sign, cross, es, ep, norms):
    """The interval of t in [lo, hi] where the leg p0 + t p1 + c d, 0 < c < s0 + s1 t (s0 = inf: unbounded),
    meets the triangle of `edges` (plane normal . x = offset); empty (hi <= lo) where the leg runs along its plane.
    sign +1 / -1: widened / narrowed (module docstring) by the crossing's error cross / |q| (its numerator's),
    es more on c < s0 + s1 t, and the point's ep (per unit of the edge rows' `norms`) on the edge tests; q = 0
    widened: all of [lo, hi]. q0, q1 (3,): scratch."""
    q = normal[0] * d[0] + normal[1] * d[1] + normal[2] * d[2]
    if q == 0.0:
        return (lo, hi) if sign > 0 else (lo, -math.inf)
    c0, c1 = _crossing(normal, offset, p0, p1, d)
    ec = sign * cross / abs(q) if sign != 0 else 0.0
    lo, hi = _clip(lo, hi, c0 + ec if sign != 0 else c0, c1)
    if s0 < math.inf:
        lo, hi = _clip(lo, hi, s0 - c0 + ec + sign * es if sign != 0 else s0 - c0, s1 - c1)
    if not hi > lo:
        return lo, hi
    for k in range(3):
        q0[k], q1[k] = p0[k] + c0 * d[k], p1[k] + c1 * d[k]
    return _in_triangle(lo, hi, edges, q0, q1, sign, abs(ec) + ep, norms)


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
def _span(owner, span, n, i, s, a, b, alpha, beta, es):
    """Record [a, b] (if b > a) as span n of beam i on segment s, with the least exponent g_min of the beam's
    integrand on it (module docstring: g = t + s_F >= t, s_F = alpha + beta t off by es); returns the new count,
    or -1 where owner and span are full."""
    if not b > a:
        return n
    if n >= owner.shape[0]:
        return -1
    owner[n, 0], owner[n, 1] = i, s
    span[n, 0], span[n, 1] = a, b
    span[n, 2] = max(a, min(a + alpha + beta * a, b + alpha + beta * b) - es)
    return n + 1


@njit
def _uncertain(owner, span, n, i, s, wlo, whi, nlo, nhi, alpha, beta, es):
    """`_span` of W = [wlo, whi] less N = [nlo, nhi] (N in W; N empty: all of W)."""
    if not nhi > nlo:
        return _span(owner, span, n, i, s, wlo, whi, alpha, beta, es)
    n = _span(owner, span, n, i, s, wlo, nlo, alpha, beta, es)
    return n if n < 0 else _span(owner, span, n, i, s, nhi, whi, alpha, beta, es)


@njit
def _blocker_spans(edges, norms, normal, offset, p0, p1, d, lo, hi, s0, s1, q0, q1, cross, es, ep, tested, owner, span,
                   n, i, s, alpha, beta, es_f):
    """`_uncertain` of a blocker's widened and narrowed sets (`_blocked`) within [lo, hi] (F's narrowed interval);
    a blocker the computed pieces did not test (not `tested`) counts its whole widened set."""
    wlo, whi = _blocked(edges, normal, offset, p0, p1, d, lo, hi, s0, s1, q0, q1, 1, cross, es, ep, norms)
    if not whi > wlo:
        return n
    nlo, nhi = lo, -math.inf
    if tested:
        nlo, nhi = _blocked(edges, normal, offset, p0, p1, d, lo, hi, s0, s1, q0, q1, -1, cross, es, ep, norms)
    return _uncertain(owner, span, n, i, s, wlo, whi, nlo, nhi, alpha, beta, es_f)


@njit
def _widened(out, box, e):
    for j in range(3):
        out[j], out[3 + j] = box[j] - e, box[3 + j] + e


@njit
def crossing_error(err, offset, r, e0, du):
    """The numerator of a crossing's error (module docstring): dc + sqrt(3) dn R + 16u (|c| + R) + e_0 + R du (err:
    the plane's `face_errors` row; r, e0, du scalars or arrays alike)."""
    return err[1] + SQ3 * err[0] * r + 16.0 * U * (np.abs(offset) + r) + e0 + r * du


@njit
def end_bounds(owner, span, towards, scales, dirs, kt, ks, code, g, out):
    """out (N, C) += per unit intensity, each of `beam_pieces`' spans' length times its beam's largest integrand on
    it, scale ks Phi exp(-kt g_min) (module docstring; scales: the beams' irradiance, Phi at towards . dirs)."""
    for j in range(owner.shape[0]):
        i, s = owner[j, 0], owner[j, 1]
        u, w = towards[i], dirs[s]
        ph = phase_value(code, g, u[0] * w[0] + u[1] * w[1] + u[2] * w[2])
        for c in range(kt.shape[0]):
            out[s, c] += scales[i] * ks[c] * ph * (span[j, 1] - span[j, 0]) * math.exp(-kt[c] * max(span[j, 2], 0.0))


@njit
def beam_pieces(edges, norms, errs, planes, boxes, size, reach, faces, towards, du, axis, origins, dirs, lengths, first,
                beam, src, x0, x1, owner, span):
    """The pieces (beam: index into faces, src: segment, x0, x1; by beam, then segment and t) of the segments
    origins + t dirs, t in [0, lengths], that each face's beam lights (module docstring; towards (B, 3): minus each
    beam's direction inside, unit, off by du (B,); edges: `edge_planes`, norms (T, 3) their rows' norms, errs (T, 4)
    `face_errors`; planes (T, 4): the triangles' unit normals and offsets, any orientation; boxes (T, 6): their
    bounding boxes, size: the diagonal of the shape's, reach: twice its largest vertex norm). A blocker is tested
    only where its box meets the box of the legs: the inside legs' ends X and P at the interval's ends, the outside
    legs' from P over `size` toward the light (beyond, nothing of the shape). The spans where the true pieces may
    differ (module docstring): owner (beam, segment), span (a, b, g_min), none where owner has no rows (the pieces
    alone, for the rules without a bound). From beam `first` on; returns the numbers of pieces and spans and the
    beam it stopped at: faces' length, or the first beam that did not fit in the arrays (the counts then those of
    the beams before it)."""
    back = -axis
    cuts = np.empty((2 * planes.shape[0], 2))
    p0, p1, q0, q1 = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    inner, outer, still, far = np.empty(6), np.empty(6), np.zeros(3), size * back
    inner_w, outer_w = np.empty(6), np.empty(6)
    bounded = owner.shape[0] > 0
    k, n = 0, 0
    for i in range(first, faces.shape[0]):
        f, toward = faces[i], towards[i]
        k_i, n_i = k, n
        nf, cf = planes[f, :3], planes[f, 3]
        qf = abs(nf[0] * toward[0] + nf[1] * toward[1] + nf[2] * toward[2])
        for s in range(origins.shape[0]):
            o, w = origins[s], dirs[s]
            alpha, beta = _crossing(nf, cf, o, w, toward)
            nlo, nhi, r, es, e_p = 0.0, -1.0, 0.0, 0.0, 0.0
            if bounded:
                r = math.sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]) + lengths[s] + reach
                es = 2.0 * crossing_error(errs[f], cf, r, 0.0, du[i]) / qf
                wlo, whi = _clip(0.0, lengths[s], alpha + es, beta)
                if not whi > wlo:  # the computed interval lies in it
                    continue
            lo, hi = _clip(0.0, lengths[s], alpha, beta)
            if not (bounded or hi > lo):
                continue
            for j in range(3):
                p0[j], p1[j] = o[j] + alpha * toward[j], w[j] + beta * toward[j]
            if bounded:
                e_p = es + 2.0 * (r * du[i] + 16.0 * U * r)
                e_f = e_p + 2.0 * (errs[f, 2] * r + errs[f, 3])
                wlo, whi = _in_triangle(wlo, whi, edges[f], p0, p1, 1, e_f, norms[f])
                if not whi > wlo:
                    continue
                nlo, nhi = _clip(0.0, lengths[s], alpha - es, beta)
                nlo, nhi = _in_triangle(nlo, nhi, edges[f], p0, p1, -1, e_f, norms[f])
                n = _uncertain(owner, span, n, i, s, wlo, whi, nlo, nhi, alpha, beta, es)
                if n < 0:
                    return k_i, n_i, i
                if not hi > lo:
                    continue
            lo, hi = _in_triangle(lo, hi, edges[f], p0, p1, 0, 0.0, norms[f])
            if not hi > lo:
                continue
            track = nhi > nlo  # bounded, and not all of W counted
            _box(inner, o, w, p0, p1, lo, hi, still)
            _box(outer, p0, p1, p0, p1, lo, hi, far)
            _widened(inner_w, inner, e_p + 16.0 * U * r if track else 0.0)
            _widened(outer_w, outer, e_p + 16.0 * U * r if track else 0.0)
            m = 0
            for g in range(planes.shape[0]):
                if g == f:
                    continue
                ng, cg = planes[g, :3], planes[g, 3]
                wide = _meets(inner_w, boxes[g])  # holds inner
                tested = wide and _meets(inner, boxes[g])
                if tested:
                    a, b = _blocked(edges[g], ng, cg, o, w, toward, lo, hi, alpha, beta, q0, q1, 0, 0.0, 0.0, 0.0,
                                    norms[g])
                    if b > a:
                        cuts[m, 0], cuts[m, 1] = a, b
                        m += 1
                if track and wide and norms[g, 0] > 0.0:
                    n = _blocker_spans(edges[g], norms[g], ng, cg, o, w, toward, nlo, nhi, alpha, beta, q0, q1,
                                       2.0 * crossing_error(errs[g], cg, r, 0.0, du[i]), es,
                                       2.0 * (r * du[i] + 16.0 * U * r + errs[g, 2] * r + errs[g, 3]), tested, owner,
                                       span, n, i, s, alpha, beta, es)
                    if n < 0:
                        return k_i, n_i, i
                wide = _meets(outer_w, boxes[g])  # holds outer
                tested = wide and _meets(outer, boxes[g])
                if tested:
                    a, b = _blocked(edges[g], ng, cg, p0, p1, back, lo, hi, math.inf, 0.0, q0, q1, 0, 0.0, 0.0, 0.0,
                                    norms[g])
                    if b > a:
                        cuts[m, 0], cuts[m, 1] = a, b
                        m += 1
                if track and wide and norms[g, 0] > 0.0:
                    n = _blocker_spans(edges[g], norms[g], ng, cg, p0, p1, back, nlo, nhi, math.inf, 0.0, q0, q1,
                                       2.0 * crossing_error(errs[g], cg, r, e_p, 0.0), 0.0,
                                       2.0 * (e_p + 16.0 * U * r + errs[g, 2] * r + errs[g, 3]), tested, owner, span,
                                       n, i, s, alpha, beta, es)
                    if n < 0:
                        return k_i, n_i, i
                if m and cuts[m - 1, 0] <= lo and cuts[m - 1, 1] >= hi:  # blocked whole
                    break
            start = k
            k = _subtract(lo, hi, cuts, m, s, src, x0, x1, k)
            if k < 0:
                return k_i, n_i, i
            beam[start:k] = i
    return k, n, faces.shape[0]


def face_errors(tris, planes):
    """(T, 4) per triangle (dn, dc, de, do): how far its plane (`planes`: face_planes', unit normal and offset) may
    be from the triangle's own (dn on each normal component, dc as interiors/shapes.py measured_plane_errors has it:
    the vertices' largest |n.v - c| plus sqrt(3) dn |v| and 8u (|c| + |v|)) and its `edge_planes` rows (e, o) from
    the exact ones, relative to |e| (de: |e - e*| / |e| + 8u; do: |o - o*| / |e| + 8u |a|), each measured against
    the same in long doubles (64-bit significands: their own error is below 8u). Zero rows for triangles of zero
    area."""
    tris = np.asarray(tris, dtype=np.float64)
    t = tris.astype(np.longdouble)
    cross = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    area = np.sqrt(np.sum(cross * cross, axis=1))
    live = area > 0
    n = cross / np.where(live, area, 1)[:, None]
    verts = np.sqrt(np.sum(t * t, axis=2)).max(axis=1)
    dn = np.abs(planes[:, :3] - n).max(axis=1) + 8.0 * U
    off = np.abs(np.einsum("tvk,tk->tv", t, planes[:, :3].astype(np.longdouble)) - planes[:, 3, None]).max(axis=1)
    dc = off + SQ3 * dn * verts + 8.0 * U * (np.abs(planes[:, 3]) + verts)
    edges = edge_planes(tris)
    norms = np.linalg.norm(edges[:, :, :3], axis=2)
    de, do = np.zeros(len(tris)), np.zeros(len(tris))
    for k in range(3):
        a, b = t[:, k], t[:, (k + 1) % 3]
        e = np.cross(cross, b - a)
        scale = np.where(norms[:, k] > 0.0, norms[:, k], 1.0)
        de = np.maximum(de, (np.sqrt(np.sum((edges[:, k, :3] - e) ** 2, axis=1)) / scale).astype(float))
        do = np.maximum(do, (np.abs(edges[:, k, 3] - np.sum(e * a, axis=1)) / scale
                             + 8.0 * U * np.sqrt(np.sum(a * a, axis=1))).astype(float))
    out = np.column_stack([dn.astype(float), dc.astype(float), de + 8.0 * U, do])
    out[~live] = 0.0
    return np.ascontiguousarray(out)


def lit_pieces(tris, planes, errs, faces, towards, du, axis, origins, dirs, lengths, bounded=True):
    """`beam_pieces` of the triangles tris (T, 3, 3) (errs: `face_errors`; du (B,) the beams' direction errors) as
    arrays (beam, src, x0, x1), ordered by beam, segment and t, and its spans as (owner (S, 2), span (S, 3)) (none
    unless `bounded`)."""
    boxes = np.concatenate([tris.min(axis=1), tris.max(axis=1)], axis=1)
    size = float(np.linalg.norm(boxes[:, 3:].max(axis=0) - boxes[:, :3].min(axis=0)))
    reach = 2.0 * float(np.linalg.norm(tris, axis=2).max(initial=0.0))
    edges = edge_planes(tris)
    cap = 4 * len(lengths) + 16
    args = (edges, np.ascontiguousarray(np.linalg.norm(edges[:, :, :3], axis=2)), np.ascontiguousarray(errs),
            np.ascontiguousarray(planes), np.ascontiguousarray(boxes), size, reach,
            np.ascontiguousarray(faces, dtype=np.int64), np.ascontiguousarray(towards, dtype=np.float64),
            np.ascontiguousarray(du, dtype=np.float64), np.ascontiguousarray(axis, dtype=np.float64),
            np.ascontiguousarray(origins, dtype=np.float64), np.ascontiguousarray(dirs, dtype=np.float64),
            np.ascontiguousarray(lengths, dtype=np.float64))
    pieces, spans, first = [], [], 0
    while True:  # the beams that did not fit go on in arrays four times as long
        beam, src, x0, x1 = np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap), np.empty(cap)
        rows = 2 * cap if bounded else 0
        owner, span = np.empty((rows, 2), np.int64), np.empty((rows, 3))
        k, n, first = beam_pieces(*args, first, beam, src, x0, x1, owner, span)
        pieces.append((beam[:k], src[:k], x0[:k], x1[:k]))
        spans.append((owner[:n], span[:n]))
        if first == len(faces):
            return tuple(np.concatenate(a) for a in zip(*pieces)), tuple(np.concatenate(a) for a in zip(*spans))
        cap *= 4
