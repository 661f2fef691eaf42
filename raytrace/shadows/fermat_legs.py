"""Volumetric shadows of a point or spot light refracted into a convex shape: the pieces of camera
segments inside the shape that the light reaches through one face past every occluder.

Face f (outward unit normal n, plane n.q = c) refracts the light at L (height hl = n.L - c > 0) to a
point X(x) = p + x w inside along Fermat's path (media/slab.py `refraction_point`): the outside leg
from L to the refraction point R(x) on f's plane and the inside leg from R(x) to X(x). X is lit
through f where neither leg meets an occluder: the outside leg none of the blockers but the shape
itself, the inside leg none of the blockers clipped to the shape (shadows/beams.py `blockers_inside`).
R(x) moves on a curve of f's plane, not a line, so the frusta's linear exact intervals do not apply;
the breaks of the lit set are found as roots, not sampled.

Breaks. Whether a segment S(x) whose ends move continuously meets a closed triangle T changes only
where S(x) meets T's boundary or an end of S(x) meets T. So every break of the lit set is a root of
one of these functions of x (E0, E1 an occluder's edge, e = E1 - E0):
- outside leg through an edge:  g = ((E1 - E0) x (L - E0)) . (R - E0)  (R on the plane of L and
  the edge: its shadow edge on f's plane);
- inside leg through an edge:   g = ((R - E0) x (X - E0)) . e  (the leg coplanar with the edge);
- R through an occluder's plane (only for occluders that reach f's plane), and X through an
  inside occluder's plane (linear in x: solved in closed form).
Contacts outside the edge segment or the leg give extra breaks, which cost nothing but a piece
boundary: each interval between breaks is classified at its midpoint by exact float64
segment-triangle tests of both legs.

The roots are isolated with a Lipschitz bound on R, so that none is missed (no grid). In f's plane
let L_f, X_f(x) = p_f + x w_h be the feet of L and X (|w_h| = sqrt(1 - a^2), a = -w.n), rho = |X_f - L_f|
and z = z0 + a x the depth of X. Fermat's path lies in the vertical plane through L and X, so
R = L_f + s u with u = (X_f - L_f) / rho (the azimuth of X_f seen from L_f, monotone along the
line X_f(x)) and s = rho - r, r = z tan(t2) (t2 the angle of refraction, increasing in s), solving
rho = s + z T(s), T = tan t2. Differentiating, s' = (rho' - a T) / (1 + z T'(s)) with T' >= 0, z >= 0,
and |s u'| = (s / rho) |w_h, across u| <= |w_h, across u|, rho' = w_h.u; hence
    |R'(x)| <= |w_h| + |a| T(s) <= sqrt(1 - a^2) + |a| min(1 / sqrt(eta^2 - 1) [eta > 1], rho / z),
since sin t2 <= 1 / eta and T = r / z <= rho / z. On [x0, x1], rho is convex in x and z linear, so
rho <= max(rho(x0), rho(x1)) and z >= min(z(x0), z(x1)): K_R, a bound on |R'| there. Then
|g'| <= |(E1 - E0) x (L - E0)| K_R for the outside leg and, writing the inside one as
g = m(x) . (R - E0) with m = e x (X - E0) linear in x, |g'| <= |e x w| max|R - E0| + max|m| K_R
(|m| convex, |R - E0| <= |R(x0) - E0| + K_R (x - x0)). An interval with
|g(x0)| + |g(x1)| > K (x1 - x0) + rounding has no root (a root would need both terms below K times its
distance to the ends); others are halved until they are excluded or shorter than RESOLUTION of the
scene's size, where a sign change is bisected to the resolution of doubles (two roots closer than
that, a sliver, are not resolved). A function near zero over a stretch (a leg sliding along an
edge's plane) is cut off after MAX_EVALS evaluations, its undecided intervals' ends taken as breaks.
Beyond the depth where X rises above f's plane face f gives no light, and there the segment is
reported lit (the integrator's face test makes it 0).
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from ..media.fermat_rounding import fermat_speed, refraction_newton
from .beams import blockers_inside

MAX_EVALS = 20000  # evaluations of one break function on one segment
ROUNDING = 1e-14  # rounding allowed in a break function's value, relative (x the scene's size)
RESOLUTION = 1e-13  # x the scene's size: intervals this short are not halved further, only bisected
_OUT_EDGE, _IN_EDGE, _R_PLANE = range(3)


def lit_pieces_of_point(prep, sid: int, planes: np.ndarray, blockers, li: int, face: int, points: np.ndarray,
                        w: np.ndarray, ell: np.ndarray):
    """(segment, x0, x1) of the pieces of the segments points + x w, x in [0, ell], inside convex
    refractive shape `sid` (face planes `planes`) that point or spot light `li` reaches through face
    `face` past the `blockers` (a mask over prep.accel.triangles, None: all), by segment and x, and
    whether each segment is lit whole (N,). Occluders are culled per segment to the boxes that can
    hold its legs."""
    accel = prep.accel
    others = prep.shape_ids != sid if blockers is None else blockers & (prep.shape_ids != sid)
    outside = accel.triangles[others]
    inside = prep.memo(("point inside", sid), lambda: blockers_inside(prep, sid, planes, others))
    own = accel.triangles[prep.shape_ids == sid].reshape(-1, 3)
    n, c = planes[face, :3], planes[face, 3]
    on = own[np.abs(own @ n - c) <= 1e-9 * accel.scale]
    lo, hi = (on.min(axis=0), on.max(axis=0)) if len(on) else (own.min(axis=0), own.max(axis=0))
    eta = float(prep.scene.shapes[sid].interior.ior)
    return _pieces(np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(w, dtype=np.float64),
                   np.ascontiguousarray(ell, dtype=np.float64), np.ascontiguousarray(n), float(c),
                   np.ascontiguousarray(prep.lights.position[li], dtype=np.float64), eta, lo, hi,
                   np.ascontiguousarray(outside, dtype=np.float64), np.ascontiguousarray(inside, dtype=np.float64),
                   float(accel.scale))


@njit
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit
def _norm(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@njit
def _refraction(x, pf, wh, z0, a, lf, hl, eta):
    """(R, rho, z): the refraction point on the face's plane of Fermat's path to p + x w, the
    horizontal distance rho between the light's foot lf and the point's foot, and the depth z >= 0."""
    xf = pf + x * wh
    z = max(z0 + a * x, 0.0)
    d = lf - xf
    rho = _norm(d)
    if rho == 0.0:
        return xf, 0.0, z
    r = refraction_newton(rho, z, hl, eta)
    return xf + (r / rho) * d, rho, z


@njit
def _hits(o, d, t_lo, t_hi, v0, v1, v2):
    """Whether o + t d, t in (t_lo, t_hi), meets the triangle (v0, v1, v2) (Moller-Trumbore)."""
    e1, e2 = v1 - v0, v2 - v0
    pv = _cross(d, e2)
    det = e1 @ pv
    if det == 0.0:
        return False
    tv = o - v0
    u = (tv @ pv) / det
    if u < 0.0 or u > 1.0:
        return False
    qv = _cross(tv, e1)
    v = (d @ qv) / det
    if v < 0.0 or u + v > 1.0:
        return False
    t = (e2 @ qv) / det
    return t_lo < t < t_hi


@njit
def _clear(o, q, tris, keep):
    """Whether the segment from o to q meets none of the kept triangles (its ends excluded)."""
    d = q - o
    for i in range(tris.shape[0]):
        if keep[i] and _hits(o, d, 1e-12, 1.0 - 1e-12, tris[i, 0], tris[i, 1], tris[i, 2]):
            return False
    return True


@njit
def _push(arr, m, v):
    if m == arr.shape[0]:
        bigger = np.empty(2 * arr.shape[0])
        bigger[:m] = arr
        arr = bigger
    arr[m] = v
    return arr


@njit
def _value(kind, x, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta):
    """A break function at x (module docstring): _OUT_EDGE vec . (R - E0) (vec = e x (L - E0));
    _IN_EDGE ((R - E0) x (X - E0)) . vec (vec = e); _R_PLANE vec . (R - E0) (vec the plane's normal)."""
    rp, _, _ = _refraction(x, pf, wh, z0, a, lf, hl, eta)
    if kind == _IN_EDGE:
        return _cross(rp - e0, p + x * w - e0) @ vec
    return vec @ (rp - e0)


@njit
def _speed(x0, x1, a, lf, pf, wh, z0, eta):
    """K_R: a bound on |R'| over [x0, x1] (module docstring)."""
    return fermat_speed(_norm(pf + x0 * wh - lf), _norm(pf + x1 * wh - lf), min(z0 + a * x0, z0 + a * x1), a, eta)


@njit
def _roots(kind, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta, end, tol, width, out, m):
    """Append to out (from m) the roots of the break function in (0, end) (module docstring):
    intervals that the Lipschitz bound does not exclude are halved down to `width`; there a sign
    change is bisected to the resolution of doubles. Returns (out, m)."""
    size = _norm(vec)
    stack = np.empty((128, 4))
    stack[0, 0], stack[0, 1] = 0.0, end
    stack[0, 2] = _value(kind, 0.0, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta)
    stack[0, 3] = _value(kind, end, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta)
    top, evals = 1, 2
    while top > 0:
        top -= 1
        lo, hi, glo, ghi = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        k = _speed(lo, hi, a, lf, pf, wh, z0, eta)
        if kind == _IN_EDGE:  # g = m(x) . (R - E0), m = e x (X - E0) linear in x
            mx = max(_norm(_cross(vec, p + lo * w - e0)), _norm(_cross(vec, p + hi * w - e0)))
            rl, _, _ = _refraction(lo, pf, wh, z0, a, lf, hl, eta)
            k = _norm(_cross(vec, w)) * (_norm(rl - e0) + k * (hi - lo)) + mx * k
        else:
            k = size * k
        if abs(glo) + abs(ghi) > k * (hi - lo) + 2.0 * tol:
            continue  # no root here
        if hi - lo <= width:
            if glo * ghi < 0.0:
                for _ in range(200):
                    mid = 0.5 * (lo + hi)
                    if not lo < mid < hi:
                        break
                    gm = _value(kind, mid, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta)
                    if gm * glo > 0.0:
                        lo, glo = mid, gm
                    else:
                        hi = mid
                out = _push(out, m, 0.5 * (lo + hi))
                m += 1
            continue
        if evals >= MAX_EVALS or top + 2 > stack.shape[0]:  # undecided: its ends are breaks
            out = _push(out, m, lo)
            out = _push(out, m + 1, hi)
            m += 2
            continue
        mid = 0.5 * (lo + hi)
        gm = _value(kind, mid, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta)
        evals += 1
        stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = mid, hi, gm, ghi
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = lo, mid, glo, gm
        top += 2
    return out, m


@njit
def _box_overlap(tri, lo, hi, pad):
    for k in range(3):
        if min(tri[0, k], tri[1, k], tri[2, k]) > hi[k] + pad or max(tri[0, k], tri[1, k], tri[2, k]) < lo[k] - pad:
            return False
    return True


@njit
def _segment_breaks(p, w, end, n, c, light, eta, flo, fhi, outside, inside, scale, keep_out, keep_in):
    """The breaks (sorted, in (0, end)) of the lit set of one segment through face (n, c), end > 0
    where X stays below the face's plane, and the occluders that can meet its legs (keep_out,
    keep_in: masks filled)."""
    hl = n @ light - c
    z0 = c - n @ p
    a = -(n @ w)
    pf, wh, lf = p + z0 * n, w + a * n, light - hl * n
    # R lies in the triangle (lf, the foot at 0, the foot at end) and, where the face lights, on the face
    x_end = p + end * w
    f0, f1 = pf, pf + end * wh
    lo, hi = np.empty(3), np.empty(3)
    for k in range(3):
        lo[k] = max(min(lf[k], f0[k], f1[k]), flo[k])
        hi[k] = min(max(lf[k], f0[k], f1[k]), fhi[k])
    pad = 1e-9 * scale
    keep_out[:] = False
    keep_in[:] = False
    out = np.empty(16)
    m = 0
    for k in range(3):
        if lo[k] > hi[k] + pad:  # R never on the face: nothing to shadow
            return out[:0]
    olo, ohi, ilo, ihi = lo.copy(), hi.copy(), lo.copy(), hi.copy()
    for k in range(3):
        olo[k], ohi[k] = min(lo[k], light[k]), max(hi[k], light[k])
        ilo[k], ihi[k] = min(lo[k], p[k], x_end[k]), max(hi[k], p[k], x_end[k])
    tol, width = ROUNDING * scale, RESOLUTION * scale
    for i in range(outside.shape[0]):
        keep_out[i] = _box_overlap(outside[i], olo, ohi, pad)
        if keep_out[i]:
            out, m = _occluder_roots(_OUT_EDGE, outside[i], light, p, w, pf, wh, z0, a, lf, hl, eta, end, n, c,
                                     tol, 1.0, width, pad, out, m)
    for i in range(inside.shape[0]):
        tri = inside[i]
        keep_in[i] = _box_overlap(tri, ilo, ihi, pad)
        if not keep_in[i]:
            continue
        out, m = _occluder_roots(_IN_EDGE, tri, light, p, w, pf, wh, z0, a, lf, hl, eta, end, n, c, tol, scale,
                                 width, pad, out, m)
        nt = _cross(tri[1] - tri[0], tri[2] - tri[0])
        den = nt @ w
        if den != 0.0:  # X through the occluder's plane
            x = (nt @ (tri[0] - p)) / den
            if 0.0 < x < end:
                out = _push(out, m, x)
                m += 1
    res = out[:m].copy()
    res.sort()
    return res


@njit
def _occluder_roots(kind, tri, light, p, w, pf, wh, z0, a, lf, hl, eta, end, n, c, tol, size, width, pad, out, m):
    """`_roots` of one occluder's edges for one leg (`_OUT_EDGE` or `_IN_EDGE`) and, where it reaches
    the face's plane, of R through its plane (`_R_PLANE`); tol: the rounding of R's position, size:
    the other length an edge function multiplies (the scene's size inside, 1 outside)."""
    for j in range(3):
        e0 = tri[j]
        e = tri[(j + 1) % 3] - e0
        vec = _cross(e, light - e0) if kind == _OUT_EDGE else e
        if _norm(vec) > 0.0:
            out, m = _roots(kind, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta, end, tol * size * _norm(vec), width,
                            out, m)
    d0, d1, d2 = n @ tri[0] - c, n @ tri[1] - c, n @ tri[2] - c
    nt = _cross(tri[1] - tri[0], tri[2] - tri[0])
    if min(d0, d1, d2) > pad or max(d0, d1, d2) < -pad or _norm(nt) == 0.0:
        return out, m
    return _roots(_R_PLANE, tri[0], nt, p, w, pf, wh, z0, a, lf, hl, eta, end, tol * _norm(nt), width, out, m)


@njit
def _pieces(points, ws, ells, n, c, light, eta, flo, fhi, outside, inside, scale):
    """`lit_pieces_of_point`'s kernel: (segment, x0, x1) of the lit pieces and whether each segment
    is lit whole."""
    nseg = points.shape[0]
    src, x0s, x1s = np.empty(nseg, np.int64), np.empty(nseg), np.empty(nseg)
    whole = np.zeros(nseg, np.bool_)
    keep_out, keep_in = np.empty(outside.shape[0], np.bool_), np.empty(inside.shape[0], np.bool_)
    cnt = 0
    hl = n @ light - c
    for s in range(nseg):
        p, w, ell = points[s], ws[s], ells[s]
        if not ell > 0.0:
            continue
        a = -(n @ w)
        z0 = c - n @ p
        end = ell if a >= 0.0 else min(ell, max(z0, 0.0) / -a)  # beyond, X is above the face's plane
        pf, wh, lf = p + z0 * n, w + a * n, light - hl * n
        bounds = np.empty(2)
        if end > 0.0:
            breaks = _segment_breaks(p, w, end, n, c, light, eta, flo, fhi, outside, inside, scale, keep_out, keep_in)
            bounds = np.empty(breaks.shape[0] + 2)
            bounds[1:-1] = breaks
        bounds[0], bounds[-1] = 0.0, end
        first, last = -1.0, -1.0
        for i in range(bounds.shape[0] - 1):
            lo, hi = bounds[i], bounds[i + 1]
            if not hi > lo:
                continue
            x = 0.5 * (lo + hi)
            rp, _, _ = _refraction(x, pf, wh, z0, a, lf, hl, eta)
            if _clear(light, rp, outside, keep_out) and _clear(rp, p + x * w, inside, keep_in):
                if first < 0.0:
                    first = lo
                last = hi
            elif first >= 0.0:
                src, x0s, x1s, cnt = _add(src, x0s, x1s, cnt, s, first, last)
                first = -1.0
        if end < ell:  # face f gives no light beyond: lit (its term is 0 there)
            if first < 0.0:
                first = end
            last = ell
        if first >= 0.0:
            src, x0s, x1s, cnt = _add(src, x0s, x1s, cnt, s, first, last)
        whole[s] = cnt > 0 and src[cnt - 1] == s and x0s[cnt - 1] == 0.0 and x1s[cnt - 1] == ell
    return src[:cnt].copy(), x0s[:cnt].copy(), x1s[:cnt].copy(), whole


@njit
def _add(src, x0s, x1s, cnt, s, lo, hi):
    if cnt == src.shape[0]:
        src = np.concatenate((src, np.empty(src.shape[0] + 1, np.int64)))
        x0s = np.concatenate((x0s, np.empty(x0s.shape[0] + 1)))
        x1s = np.concatenate((x1s, np.empty(x1s.shape[0] + 1)))
    src[cnt], x0s[cnt], x1s[cnt] = s, lo, hi
    cnt += 1
    return src, x0s, x1s, cnt
