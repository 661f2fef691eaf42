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
that, a sliver, are not resolved: a span below holds them). A function near zero over a stretch (a
leg sliding along an edge's plane) is cut off after MAX_EVALS evaluations, its undecided intervals'
ends taken as breaks (the segment's spans then unknown).
Beyond the depth where X rises above f's plane face f gives no light, and there the segment is
reported lit (the integrator's face test makes it 0).

Spans. Where the exact lit set may differ from the computed pieces (the breaks' location error of
interiors/rows.py's bound). The computed refraction point is within E of the exact one through the
face's mesh plane (`_point_error`: media/fermat_rounding.py `point_error` at the segment's worst,
with the planes' errors, plus 8u (rho + |p_f| + end + |L_f|) for `_refraction`'s own arithmetic).
For one occluder let D_L, D_R, D_X be the largest distances from its vertices to the light, to R (in
the triangle of the light's foot and the segment's feet, within E) and to X, D the largest of these
and of the legs' lengths, e_max its longest edge and nt = e1 x e2 its plane's normal. Each break
function is then within a band of its exact value, and so is the value whose sign the
segment-triangle test (`_hits`, Moller-Trumbore) reads for the same edge or plane (the edge's triple
product with the leg: the same function in exact arithmetic, rounded to 12u of the product of its
factors' lengths; u and v matter only where both lie in [0, 1], so u + v - 1 times det costs at most
four such roundings):
- an edge of an outside occluder: e_max D_L (E + 48u D); of an inside one: e_max (D_X E + D_R (2u
  (|p| + end) + 48u D)) (X = p + x w rounded);
- R through an occluder's plane: |nt| (E + 1e-12 D) + 48u e_max^2 D, the test's tolerance 1e-12 of
  the leg's length;
- X through an inside occluder's plane (closed form, x = nt.(V0 - p) / nt.w):
  |nt| (1e-12 D + 16u F) + 64u e_max^2 (D + F), F = |V0 - p| + end, the span x -+ that / |nt.w|
  (clipped to the segment); a segment parallel to the plane within that of it: unknown;
- the light within 48u e_max^2 D + 1e-12 |nt| D of an outside occluder's plane (the test's det
  could take the wrong sign): unknown.
The search goes on in every interval with |g(lo)| + |g(hi)| <= K (hi - lo) + 4 band (K enlarged by
1e-9 of it, and inside by |e x w| E for R's error in its bound), down to RESOLUTION (the breaks are
still taken where the search above takes them: the pieces do not change); elsewhere the exact
function is farther than band from 0, so its sign and the test's agree with the computed ones, and
runs of adjacent undecided intervals, the spans, hold every exact root (a computed sign change
inside one is bisected there; a span without one holds an even number of exact roots). Between
spans the exact lit set is constant over each piece and the test at a piece's midpoint reads it
right, unless the midpoint lies in a span that does not hold the whole piece (then: unknown). Over
a span the integrand through the face is between 0 and the face's term, which varies by far less
than a factor 2 over SPAN_WIDTH (media/slab.py `_isolate`'s argument): the span's error is its width
times twice the larger term at its ends (`span_errors`). Unknown (the bound inf): a span longer
than SPAN_WIDTH, a search stopped undecided (MAX_EVALS), E unknown (the segment within 1e-12 of its
length straight below the light, the light within 1e-9 of the scene's size of the face's plane)
where an occluder may meet the legs, and the cases above.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from ..media.fermat_rounding import U, fermat_speed, point_error, refraction_newton
from ..media.slab import FACE_COLUMNS, GEO_COLUMNS, fermat, only_face, refracted_at, refracting_faces, spot_terms
from .beams import blockers_inside

MAX_EVALS = 20000  # evaluations of one break function on one segment
ROUNDING = 1e-14  # rounding allowed in a break function's value, relative (x the scene's size)
RESOLUTION = 1e-13  # x the scene's size: intervals this short are not halved further, only bisected
SPAN_WIDTH = 1e-9  # x the scene's size: a longer span makes its segment's bound infinite
_OUT_EDGE, _IN_EDGE, _R_PLANE = range(3)


def lit_pieces_of_point(prep, sid: int, planes: np.ndarray, blockers, li: int, face: int, points: np.ndarray,
                        w: np.ndarray, ell: np.ndarray, dplanes: np.ndarray):
    """(segment, x0, x1) of the pieces of the segments points + x w, x in [0, ell], inside convex
    refractive shape `sid` (face planes `planes`, their errors `dplanes`: interiors/rows.py
    `measured_plane_errors`) that point or spot light `li` reaches through face `face` past the
    `blockers` (a mask over prep.accel.triangles, None: all), by segment and x, whether each segment
    is lit whole (N,), and the spans (segment, lo, hi) where the exact lit set may differ from these
    pieces with whether each segment's are known (N,) (module docstring, "Spans"). Occluders are
    culled per segment to the boxes that can hold its legs."""
    accel = prep.accel
    others = prep.shape_ids != sid if blockers is None else blockers & (prep.shape_ids != sid)
    outside = accel.triangles[others]
    inside = prep.memo(("point inside", sid), lambda: blockers_inside(prep, sid, planes, others))
    own = accel.triangles[prep.shape_ids == sid].reshape(-1, 3)
    n, c = planes[face, :3], planes[face, 3]
    on = own[np.abs(own @ n - c) <= 1e-9 * accel.scale]
    lo, hi = (on.min(axis=0), on.max(axis=0)) if len(on) else (own.min(axis=0), own.max(axis=0))
    eta = float(prep.scene.shapes[sid].interior.ior)
    src, x0, x1, whole, sseg, slo, shi, sure = _pieces(
        np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(w, dtype=np.float64),
        np.ascontiguousarray(ell, dtype=np.float64), np.ascontiguousarray(n), float(c),
        np.ascontiguousarray(prep.lights.position[li], dtype=np.float64), eta, lo, hi,
        np.ascontiguousarray(outside, dtype=np.float64), np.ascontiguousarray(inside, dtype=np.float64),
        float(accel.scale), np.asarray(dplanes, dtype=np.float64), float(np.abs(planes[:, 3]).max()))
    return src, x0, x1, whole, (sseg, slo, shi, sure)


def span_errors(prep, sid: int, planes: np.ndarray, li: int, face: int, points: np.ndarray, w: np.ndarray, spans):
    """(S, 3): a bound on the error of light li's unit single scattering through face `face` over each
    span (segment, lo, hi) of `lit_pieces_of_point` (the exact lit set unknown there): its width
    times twice the face's term (media/slab.py `refracted_at`, without the face test) at the larger
    of its ends, per colour channel (module docstring, "Spans")."""
    sseg, slo, shi, _ = spans
    medium, lights = prep.scene.shapes[sid].interior, prep.lights
    out = np.zeros((len(sseg), 3))
    if not len(sseg):
        return out
    geo = np.zeros((len(sseg), GEO_COLUMNS))
    geo[:, :3], geo[:, 3:6], geo[:, 6:9] = points[sseg], w[sseg], lights.position[li]
    geo[:, 9:12], geo[:, 12:14], geo[:, 17] = lights.axis[li], lights.cone[li, :2], lights.cone[li, 2]
    for ch in range(3):
        _span_terms(geo, np.ascontiguousarray(planes), face, slo, shi, float(medium.ior), float(medium.sigma_t[ch]),
                    float(medium.sigma_s[ch]), medium.phase, medium.g, float(prep.scene.medium.sigma_t[ch]),
                    out[:, ch])
    return out


@njit
def _span_terms(geo, planes, face, lo, hi, eta, kt, ks, code, g, kt_out, out):
    """out[s] = (hi - lo) x 2 x the larger term of face `face` at lo and hi of span s (geo rows with zero
    entry normals: the face's row from `planes`)."""
    faces = np.empty((max(planes.shape[0], 1), FACE_COLUMNS))
    for s in range(geo.shape[0]):
        spot = spot_terms(geo[s], 0.0, 0.0)
        out[s] = 0.0
        if only_face(faces, refracting_faces(geo[s], planes, 0.0, 0.0, 0.0, 0.0, spot, faces), face) == 0:
            continue
        row = faces[0]
        z0, a, hl, wl, ll = row[0], row[1], row[2], row[3], row[4]
        for x in (lo[s], hi[s]):
            if z0 + a * x > 0.0:
                rho, r = fermat(x, z0, wl, ll, a, hl, eta)
                term = refracted_at(x, z0, rho, r, wl, a, hl, eta, kt, ks, code, g, kt_out, row[5], row[6], row[7],
                                    spot[3], spot[4], spot[5])
                out[s] = max(out[s], 2.0 * term * (hi[s] - lo[s]))


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
    out, m, _, _, _ = _isolated_roots(kind, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta, end, tol, width, -1.0, 0.0, out,
                                      m, np.empty((0, 2)), 0)
    return out, m


@njit
def _isolated_roots(kind, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta, end, tol, width, band, dk, out, m, spans, ns):
    """`_roots` (out, m) and, with band >= 0 (a bound on how far the computed break function, and
    the segment-triangle test's value that it stands for, may be from the exact one; dk: what the
    exact function's Lipschitz bound may exceed the computed one by), the spans where the exact
    function may lie within band of 0 (module docstring, "Spans"): the search goes on in the
    intervals with |g(lo)| + |g(hi)| <= K (hi - lo) + 4 band, K enlarged by 1e-9 of it and dk, down
    to `width`, and runs of adjacent such intervals are appended to spans (rows lo, hi, from ns),
    the roots still taken only where the search above takes them (its breaks are unchanged).
    Returns (out, m, spans, ns, sure): sure is False where either search stopped undecided."""
    size = _norm(vec)
    stack = np.empty((256, 5))
    stack[0, 0], stack[0, 1] = 0.0, end
    stack[0, 2] = _value(kind, 0.0, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta)
    stack[0, 3] = _value(kind, end, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta)
    stack[0, 4] = 1.0  # the search of the breaks goes on here (else the spans' alone)
    top, evals, extra, found = 1, 2, 0, 1
    run_lo, run_hi, sure = -1.0, -1.0, True
    while top > 0:
        top -= 1
        lo, hi, glo, ghi, old = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3], stack[top, 4] > 0.0
        if old:
            found -= 1
        k = _speed(lo, hi, a, lf, pf, wh, z0, eta)
        if kind == _IN_EDGE:  # g = m(x) . (R - E0), m = e x (X - E0) linear in x
            mx = max(_norm(_cross(vec, p + lo * w - e0)), _norm(_cross(vec, p + hi * w - e0)))
            rl, _, _ = _refraction(lo, pf, wh, z0, a, lf, hl, eta)
            k = _norm(_cross(vec, w)) * (_norm(rl - e0) + k * (hi - lo)) + mx * k
        else:
            k = size * k
        old = old and not abs(glo) + abs(ghi) > k * (hi - lo) + 2.0 * tol
        near = band >= 0.0 and not abs(glo) + abs(ghi) > (k * (1.0 + 1e-9) + dk) * (hi - lo) + 4.0 * band
        if not (old or near):
            continue  # no root here
        if hi - lo <= width:
            if old and glo * ghi < 0.0:
                blo, bhi, gb = lo, hi, glo
                for _ in range(200):
                    mid = 0.5 * (blo + bhi)
                    if not blo < mid < bhi:
                        break
                    gm = _value(kind, mid, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta)
                    if gm * gb > 0.0:
                        blo, gb = mid, gm
                    else:
                        bhi = mid
                out = _push(out, m, 0.5 * (blo + bhi))
                m += 1
            if band >= 0.0:
                if lo != run_hi:  # a new run: close the last
                    if run_hi > run_lo:
                        spans, ns = _push_span(spans, ns, run_lo, run_hi)
                    run_lo = lo
                run_hi = hi
            continue
        if old and (evals >= MAX_EVALS or found + 2 > 128):  # undecided: its ends are breaks
            out = _push(out, m, lo)
            out = _push(out, m + 1, hi)
            m += 2
            sure = False
            continue
        if not old and extra >= MAX_EVALS or top + 2 > stack.shape[0]:
            sure = False
            continue
        mid = 0.5 * (lo + hi)
        gm = _value(kind, mid, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta)
        if old:
            evals += 1
            found += 2
        else:
            extra += 1
        stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3], stack[top, 4] = mid, hi, gm, ghi, old
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = lo, mid, glo, gm
        stack[top + 1, 4] = old
        top += 2
    if band >= 0.0 and run_hi > run_lo:
        spans, ns = _push_span(spans, ns, run_lo, run_hi)
    return out, m, spans, ns, sure


@njit
def _push_span(spans, ns, lo, hi):
    if ns == spans.shape[0]:
        bigger = np.empty((2 * spans.shape[0] + 4, 2))
        bigger[:ns] = spans[:ns]
        spans = bigger
    spans[ns, 0], spans[ns, 1] = lo, hi
    return spans, ns + 1


@njit
def _box_overlap(tri, lo, hi, pad):
    for k in range(3):
        if min(tri[0, k], tri[1, k], tri[2, k]) > hi[k] + pad or max(tri[0, k], tri[1, k], tri[2, k]) < lo[k] - pad:
            return False
    return True


@njit
def _segment_breaks(p, w, end, n, c, light, eta, flo, fhi, outside, inside, scale, keep_out, keep_in, err_r, spans):
    """(breaks, spans, ns, sure): the breaks (sorted, in (0, end)) of the lit set of one segment
    through face (n, c), end > 0 where X stays below the face's plane, the occluders that can meet
    its legs (keep_out, keep_in: masks filled) and, with err_r >= 0 (a bound on the computed
    refraction point's error, `_point_error`), the spans where the exact
    lit set may differ from the computed one (rows of spans from 0, ns of them) and whether they
    are known (sure)."""
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
    m, ns, sure = 0, 0, True
    for k in range(3):
        if lo[k] > hi[k] + pad:  # R never on the face: nothing to shadow
            return out[:0], spans, ns, sure
    olo, ohi, ilo, ihi = lo.copy(), hi.copy(), lo.copy(), hi.copy()
    for k in range(3):
        olo[k], ohi[k] = min(lo[k], light[k]), max(hi[k], light[k])
        ilo[k], ihi[k] = min(lo[k], p[k], x_end[k]), max(hi[k], p[k], x_end[k])
    tol, width = ROUNDING * scale, RESOLUTION * scale
    ends = np.empty((5, 3))  # the corners of R's triangle, the segment's ends
    ends[0], ends[1], ends[2], ends[3], ends[4] = lf, f0, f1, p, x_end
    for i in range(outside.shape[0]):
        keep_out[i] = _box_overlap(outside[i], olo, ohi, pad)
        if keep_out[i]:
            out, m, spans, ns, ok = _occluder_roots(_OUT_EDGE, outside[i], light, p, w, pf, wh, z0, a, lf, hl, eta, end,
                                                    n, c, tol, 1.0, width, pad, out, m, err_r, ends, spans, ns)
            sure = sure and ok
    for i in range(inside.shape[0]):
        tri = inside[i]
        keep_in[i] = _box_overlap(tri, ilo, ihi, pad)
        if not keep_in[i]:
            continue
        out, m, spans, ns, ok = _occluder_roots(_IN_EDGE, tri, light, p, w, pf, wh, z0, a, lf, hl, eta, end, n, c, tol,
                                                scale, width, pad, out, m, err_r, ends, spans, ns)
        sure = sure and ok
        nt = _cross(tri[1] - tri[0], tri[2] - tri[0])
        den = nt @ w
        x = (nt @ (tri[0] - p)) / den if den != 0.0 else 0.0
        if den != 0.0 and 0.0 < x < end:  # X through the occluder's plane
            out = _push(out, m, x)
            m += 1
        if err_r >= 0.0:  # where X may lie within the test's tolerance and rounding of the plane
            far, dm = _norm(tri[0] - p) + end, _reach(tri, light, ends, err_r)[4]
            band = _norm(nt) * (1e-12 * dm + 16.0 * U * far) + 64.0 * U * _longest(tri) ** 2 * (dm + far)
            if den != 0.0:
                if x + band / abs(den) > 0.0 and x - band / abs(den) < end:
                    spans, ns = _push_span(spans, ns, max(x - band / abs(den), 0.0), min(x + band / abs(den), end))
            elif abs(nt @ (p - tri[0])) <= band:
                sure = False
    if err_r < 0.0 and (np.any(keep_out) or np.any(keep_in)):
        sure = False  # R's error unknown: so are the spans
    res = out[:m].copy()
    res.sort()
    return res, spans, ns, sure


@njit
def _longest(tri):
    return max(_norm(tri[1] - tri[0]), _norm(tri[2] - tri[1]), _norm(tri[0] - tri[2]))


@njit
def _reach(tri, light, ends, err_r):
    """(D_L, D_R, D_X, the legs' longest, the largest of these) for occluder tri (module docstring,
    "Spans"): the largest distances from its vertices to the light, to R (in the triangle of
    ends[:3], within err_r) and to X (on the segment ends[3:]), and the longest leg."""
    d_l, d_r, d_x, leg = 0.0, 0.0, 0.0, 0.0
    for k in range(3):
        d_l = max(d_l, _norm(light - tri[k]))
        for j in range(3):
            d_r = max(d_r, _norm(ends[j] - tri[k]) + err_r)
        for j in range(3, 5):
            d_x = max(d_x, _norm(ends[j] - tri[k]))
    for j in range(3):
        leg = max(leg, _norm(ends[j] - light) + err_r, _norm(ends[j] - ends[3]) + err_r, _norm(ends[j] - ends[4]) + err_r)
    return d_l, d_r, d_x, leg, max(d_l, d_r, d_x, leg)


@njit
def _occluder_roots(kind, tri, light, p, w, pf, wh, z0, a, lf, hl, eta, end, n, c, tol, size, width, pad, out, m,
                    err_r, ends, spans, ns):
    """`_isolated_roots` of one occluder's edges for one leg (`_OUT_EDGE` or `_IN_EDGE`) and, where it
    reaches the face's plane, of R through its plane (`_R_PLANE`); tol: the rounding of R's position
    for the breaks' search, size: the other length an edge function multiplies (the scene's size
    inside, 1 outside); err_r >= 0: the spans' R error (module docstring, "Spans"; ends: the corners of
    R's triangle and the segment's ends), err_r < 0: no spans. Returns (out, m, spans, ns, sure); not sure also where the light may lie within the
    test's tolerance of an outside occluder's plane."""
    sure = True
    e_max = _longest(tri)
    nt = _cross(tri[1] - tri[0], tri[2] - tri[0])
    d_l, d_r, d_x, _, dm = _reach(tri, light, ends, err_r)
    plane_band = 48.0 * U * e_max * e_max * dm + 1e-12 * _norm(nt) * dm
    if err_r >= 0.0 and kind == _OUT_EDGE and abs(nt @ (light - tri[0])) <= plane_band:
        sure = False
    for j in range(3):
        e0 = tri[j]
        e = tri[(j + 1) % 3] - e0
        vec = _cross(e, light - e0) if kind == _OUT_EDGE else e
        band = -1.0
        if err_r >= 0.0 and kind == _OUT_EDGE:
            band = e_max * d_l * (err_r + 48.0 * U * dm)
        elif err_r >= 0.0:
            band = e_max * (d_x * err_r + d_r * (2.0 * U * (_norm(p) + end) + 48.0 * U * dm))
        dk = _norm(_cross(e, w)) * err_r if kind == _IN_EDGE and err_r >= 0.0 else 0.0
        if _norm(vec) > 0.0:
            out, m, spans, ns, ok = _isolated_roots(kind, e0, vec, p, w, pf, wh, z0, a, lf, hl, eta, end,
                                                    tol * size * _norm(vec), width, band, dk, out, m, spans, ns)
            sure = sure and ok
    d0, d1, d2 = n @ tri[0] - c, n @ tri[1] - c, n @ tri[2] - c
    if min(d0, d1, d2) > pad or max(d0, d1, d2) < -pad or _norm(nt) == 0.0:
        return out, m, spans, ns, sure
    band = _norm(nt) * err_r + plane_band if err_r >= 0.0 else -1.0
    out, m, spans, ns, ok = _isolated_roots(_R_PLANE, tri[0], nt, p, w, pf, wh, z0, a, lf, hl, eta, end,
                                            tol * _norm(nt), width, band, 0.0, out, m, spans, ns)
    return out, m, spans, ns, sure and ok


@njit
def _pieces(points, ws, ells, n, c, light, eta, flo, fhi, outside, inside, scale, dplanes, offset):
    """`lit_pieces_of_point`'s kernel: (segment, x0, x1) of the lit pieces, whether each segment is
    lit whole, (segment, lo, hi) of the spans where the exact lit set may differ from the computed
    one, merged, and whether each segment's are known (module docstring, "Spans"; dplanes: the
    planes' errors, offset: the largest |c_f|)."""
    nseg = points.shape[0]
    src, x0s, x1s = np.empty(nseg, np.int64), np.empty(nseg), np.empty(nseg)
    whole = np.zeros(nseg, np.bool_)
    sure = np.ones(nseg, np.bool_)
    keep_out, keep_in = np.empty(outside.shape[0], np.bool_), np.empty(inside.shape[0], np.bool_)
    spans = np.empty((16, 2))
    sseg, slo, shi = np.empty(16, np.int64), np.empty(16), np.empty(16)
    cnt, nspan = 0, 0
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
        merged = np.empty((0, 2))
        if end > 0.0:
            err_r = _point_error(p, end, light, hl, z0, a, pf, wh, lf, eta, dplanes, offset)
            breaks, spans, ns, sure[s] = _segment_breaks(p, w, end, n, c, light, eta, flo, fhi, outside, inside, scale,
                                                         keep_out, keep_in, err_r, spans)
            merged = _merge(spans[:ns])
            sure[s] = sure[s] and _widest(merged) <= SPAN_WIDTH * scale
            bounds = np.empty(breaks.shape[0] + 2)
            bounds[1:-1] = breaks
        bounds[0], bounds[-1] = 0.0, end
        first, last = -1.0, -1.0
        for i in range(bounds.shape[0] - 1):
            lo, hi = bounds[i], bounds[i + 1]
            if not hi > lo:
                continue
            x = 0.5 * (lo + hi)
            if not _classified(merged, lo, hi, x):
                sure[s] = False
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
        for i in range(merged.shape[0]):
            sseg, slo, shi, nspan = _add(sseg, slo, shi, nspan, s, merged[i, 0], merged[i, 1])
    return (src[:cnt].copy(), x0s[:cnt].copy(), x1s[:cnt].copy(), whole, sseg[:nspan].copy(), slo[:nspan].copy(),
            shi[:nspan].copy(), sure)


@njit
def _point_error(p, end, light, hl, z0, a, pf, wh, lf, eta, dplanes, offset):
    """A bound on the error of the refraction point R(x) that `_refraction` computes over [0, end], against
    the exact one through the face's mesh plane (media/fermat_rounding.py `point_error` at the
    segment's worst, the planes' errors dplanes, plus 8u rho and 8u (|p_f| + end + |L_f|) for R's own
    arithmetic); -1
    where it is unknown (the segment passes within 1e-12 of its size below the light, or the light
    within 1e-9 of it of the face's plane)."""
    d = lf - pf
    rho0, rho1 = _norm(d), _norm(d - end * wh)
    rho_min, rho_max = min(rho0, rho1), max(rho0, rho1)
    hh = wh @ wh
    if hh > 0.0 and 0.0 < (wh @ d) / hh < end:
        rho_min = _norm(d - ((wh @ d) / hh) * wh)
    z_max = max(z0, z0 + a * end, 0.0)
    mags = (_norm(p), _norm(light), _norm(light - p), _norm(p) + end + _norm(light) + offset)
    if not (rho_min > 1e-12 * (hl + z_max + end) and hl > 1e-9 * mags[3] and eta > 1.0):
        return -1.0
    e = point_error(end, math.sqrt(rho_max * rho_max + z_max * z_max), rho_max, hl, d @ d, rho_min, eta, dplanes[0],
                    dplanes[1], mags, False)
    return e + 8.0 * U * (rho_max + _norm(pf) + end + _norm(lf)) if e < math.inf else -1.0


@njit
def _merge(spans):
    """The union of the intervals spans (rows lo, hi), sorted, as rows."""
    if spans.shape[0] == 0:
        return spans
    order = np.argsort(spans[:, 0])
    out = np.empty_like(spans)
    k = 0
    out[0] = spans[order[0]]
    for i in order[1:]:
        if spans[i, 0] <= out[k, 1]:
            out[k, 1] = max(out[k, 1], spans[i, 1])
        else:
            k += 1
            out[k] = spans[i]
    return out[:k + 1]


@njit
def _widest(merged):
    wid = 0.0
    for i in range(merged.shape[0]):
        wid = max(wid, merged[i, 1] - merged[i, 0])
    return wid


@njit
def _classified(merged, lo, hi, x):
    """Whether the piece [lo, hi] classified at x is classified right: x outside every span, or the
    piece inside the span that holds x (its error counted with the span's)."""
    for i in range(merged.shape[0]):
        if merged[i, 0] <= x <= merged[i, 1]:
            return merged[i, 0] <= lo and hi <= merged[i, 1]
    return True


@njit
def _add(src, x0s, x1s, cnt, s, lo, hi):
    if cnt == src.shape[0]:
        src = np.concatenate((src, np.empty(src.shape[0] + 1, np.int64)))
        x0s = np.concatenate((x0s, np.empty(x0s.shape[0] + 1)))
        x1s = np.concatenate((x1s, np.empty(x1s.shape[0] + 1)))
    src[cnt], x0s[cnt], x1s[cnt] = s, lo, hi
    cnt += 1
    return src, x0s, x1s, cnt
