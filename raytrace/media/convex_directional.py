"""Exact single scattering of a directional light along a segment inside a convex polyhedron filled
with a homogeneous medium: the light enters through whichever face its path meets, not through the
plane of the camera ray's entry face as the planar model of slab.py.

Geometry: the segment p(t) = o + t w, t in [0, T] (w unit), inside {x : n_f·x <= c_f, f = 1..F}
(n_f outward unit normals); u = -d_light the unit direction toward the light. The light's path
inside from p(t) to the boundary has length

    s(t) = max(0, min_{f : q_f > 0} s_f(t)),   s_f(t) = alpha_f + beta_f t,                     (1)
    q_f = n_f·u,  alpha_f = (c_f - n_f·o) / q_f,  beta_f = -(n_f·w) / q_f,

the lower envelope of the faces the light crosses (q_f > 0; faces parallel to the light, q_f = 0,
are never crossed): concave and piecewise linear, with at most F pieces (`envelope`). The
clamp at 0 (slab.convex_exit_face's) matters only for points off the shape by rounding. Per unit
irradiance, with Phi the phase value at the scattering cosine u·w (constant along the segment),

    L = ks Phi ∫_0^T exp(-kt (t + s(t))) dt,                                                      (2)

and on a piece [t0, t1] where g(t) = t + s(t) is linear (g0, g1 at its ends, slope g'),

    ∫_{t0}^{t1} exp(-kt g) dt = exp(-kt min(g0, g1)) (t1 - t0) phi(-kt |g'| (t1 - t0)),          (3)
    phi(z) = expm1(z) / z  (phi(0) = 1),

written from the end with the larger exponent, so that phi's argument is <= 0: phi lies in (0, 1]
and the exponent is <= 0 (g >= 0), so (3) neither overflows nor cancels, for kt (1 + |beta|) T
from 0 to far beyond 745 (exp underflows to 0, never NaN). A last piece of infinite length
(T = inf: g' >= 1 there) is exp(-kt g0) / (kt g'). kt = 0 gives ks Phi T (a vacuum transmits
over any length, also where no face faces the light); kt > 0 with no face toward the light gives
0 (an infinite path).

Through a refractive boundary the light makes one beam per face it meets (interiors/fresnel.py refracted_beams),
each with its own direction inside; beam f lights a point only where the point's path back leaves
through f, i.e. on the envelope's pieces on face f (`only` = f below).

`MAX_FACES` bounds F: the envelope's sweep costs O(F x pieces) per segment, and a shape with
more faces returns False (nothing computed) so that the caller integrates it otherwise. There, one
beam at a time, `beam_intervals` finds where beam f lights a segment without the envelope: the point
Y(t) = p(t) + s_f(t) u where the path back leaves plane f is on face f iff it lies inside the planes of
f's neighbours that the light crosses (n_g·Y <= c_g, q_g > 0; the others hold at every point inside),
each a linear inequality in t: one interval per segment, O(neighbours) per beam, and the envelope's
piece on f exactly (s_f <= s_g is n_g·Y(t) <= c_g). `beams_closed` integrates (2) over it by (3).
Accuracy: a few 1e-14 relative, 1e-12 at worst, against a 40-digit twin of (2) with s by brute
force (tests/test_convex_directional.py), but where the answer itself is ill-conditioned in
doubles: a segment ending on a face the light grazes (q_f ~ 1e-9) is lit mostly in its last
~1e-10, where s rests on (c_f - n_f·p) / q_f, rounded to 1e-17 / q_f (1.5e-5 measured at kt = 745,
which the last bit of T moves as much).
"""
import math

import numpy as np

from ..error_bounds import KERNEL_FLOOR
from ..jit import njit
from .phase import phase_value

MAX_FACES = 64  # beyond, interiors/rows.py hands the segments to quadrature (counted)
EPS = 2.0 ** -52


@njit
def envelope(n, c, o, w, toward, length, alpha, beta, cuts, lines):
    """The lower envelope of the lines s_f(t) of (1) over [0, length]: returns m, the number of pieces,
    piece i spanning [cuts[i], cuts[i + 1]] on face lines[i] (alpha, beta: (F,) scratch, filled
    with (1)'s coefficients, inf for faces the light does not cross; cuts (F + 1,), lines (F,));
    0 when no face faces the light or length is not > 0. The sweep starts on the lowest line at
    t = 0 (the least steep of equals) and moves on to the line of smaller slope that crosses it
    first (the steepest of simultaneous ones): the slopes fall at every step, so each face is
    visited at most once."""
    k = -1
    for f in range(n.shape[0]):
        q = n[f, 0] * toward[0] + n[f, 1] * toward[1] + n[f, 2] * toward[2]
        if q > 0.0:
            alpha[f] = (c[f] - (n[f, 0] * o[0] + n[f, 1] * o[1] + n[f, 2] * o[2])) / q
            beta[f] = -(n[f, 0] * w[0] + n[f, 1] * w[1] + n[f, 2] * w[2]) / q
            if k < 0 or alpha[f] < alpha[k] or (alpha[f] == alpha[k] and beta[f] < beta[k]):
                k = f
        else:
            alpha[f] = math.inf
            beta[f] = math.inf
    if k < 0 or not length > 0.0:
        return 0
    m = 0
    t = 0.0
    while True:
        nxt = -1
        first = length
        for f in range(n.shape[0]):
            if beta[f] < beta[k]:
                tc = (alpha[f] - alpha[k]) / (beta[k] - beta[f])
                if tc < first or (tc == first and nxt >= 0 and beta[f] < beta[nxt]):
                    first = tc
                    nxt = f
        cuts[m] = t
        lines[m] = k
        m += 1
        if nxt < 0:
            break
        t = max(first, t)  # a crossing rounded to before t: the lower line takes over at once
        k = nxt
    cuts[m] = length
    return m


@njit
def exp_linear(kt, g0, g1, slope, d):
    """Eq. (3): ∫_0^d exp(-kt g(x)) dx for g linear from g0 (x = 0) to g1 (x = d), slope g' (kt > 0,
    g >= 0); d = inf needs slope > 0 (g1 unused)."""
    if not d > 0.0:
        return 0.0
    if d == math.inf:
        return math.exp(-kt * g0) / (kt * slope)
    z = -kt * abs(slope) * d
    phi = 1.0 if z == 0.0 else math.expm1(z) / z
    return math.exp(-kt * min(g0, g1)) * d * phi


@njit
def _accumulate(kt, ks, phase, t0, t1, a, b, out):
    """out[ch] += ks Phi ∫_{t0}^{t1} exp(-kt (t + s)) dt on one piece of the envelope, s = max(0, a + b t):
    the line on [lo, hi], s = 0 before and after it (the clamp of (1), where a + b t crosses 0);
    kt = 0 channels are left out."""
    s0 = a + b * t0
    s1 = a + b * t1 if t1 < math.inf or b != 0.0 else a
    lo, hi = t0, t1
    if s0 < 0.0 and s1 < 0.0:
        hi = t0
    elif s0 < 0.0:
        lo = min(-a / b, t1)
    elif s1 < 0.0:
        hi = max(-a / b, t0)
    for ch in range(kt.shape[0]):
        if ks[ch] == 0.0 or kt[ch] == 0.0:
            continue
        v = exp_linear(kt[ch], t0, lo, 1.0, lo - t0) + exp_linear(kt[ch], hi, t1, 1.0, t1 - hi)
        if hi > lo:
            g0 = lo + max(a + b * lo, 0.0)
            g1 = hi + max(a + b * hi, 0.0) if hi < math.inf else g0
            v += exp_linear(kt[ch], g0, g1, 1.0 + b, hi - lo)
        out[ch] += ks[ch] * phase * v


@njit
def _pieces(n, c, o, w, toward, length, kt, ks, phase, out, alpha, beta, cuts, lines, only):
    """Eq. (2) into out; returns the number of the envelope's pieces (left in cuts, lines). only >= 0:
    the light reaches the segment only where its path leaves through face `only` (one refracted
    beam, `refracted_beams`): the pieces on other faces are left out, also for kt = 0."""
    for ch in range(kt.shape[0]):
        out[ch] = ks[ch] * phase * length if kt[ch] == 0.0 and length > 0.0 and only < 0 else 0.0
    m = envelope(n, c, o, w, toward, length, alpha, beta, cuts, lines)
    for i in range(m):
        f = lines[i]
        if only >= 0 and f != only:
            continue
        _accumulate(kt, ks, phase, cuts[i], cuts[i + 1], alpha[f], beta[f], out)
        if only >= 0:
            for ch in range(kt.shape[0]):
                if kt[ch] == 0.0:
                    out[ch] += ks[ch] * phase * (cuts[i + 1] - cuts[i])
    return m


@njit
def beam_intervals(n, c, near, f, toward, origins, dirs, lengths, dplanes, du, out):
    """Where beam f (the light refracted through face f, travelling along -toward inside, q_f > 0) lights
    each segment (origins, dirs (N, 3), lengths (N,)) of the convex polyhedron (n, c: P planes; near:
    interiors/shapes.py `plane_neighbours`' packed lists, f's neighbours near[near[f]:near[f + 1]];
    empty: every plane): out (N, 9) = (lo, hi, lo_a, lo_b, hi_a, hi_b, alpha, beta, es): the computed
    interval [lo, hi] (lo >= hi: unlit); the true interval's ends lie in [lo_a, lo_b] and [hi_a, hi_b]
    where the planes are (dn, dc) = `dplanes` off the faces (dn per component) and the arithmetic rounds
    and toward is du off the beam's true direction (each inequality's h_g(t) = c_g - n_g·Y(t) = A + B t
    is off by at most e_g = (dc + sqrt(3) dn R_Y + 16u (|c_g| + |c_f| + 2 R_Y) + R_Y du) (1 + q_g / q_f)
    over the segment to first order, R_Y bounding |Y| and s_f: the true set {h_g >= 0} lies between
    {A + B t >= e_g} and {A + B t >= -e_g}); alpha, beta of (1) for face f; es = (dc + sqrt(3) dn R_Y +
    16u (|c_f| + R_Y) + R_Y du) / q_f bounds s_f's own error."""
    q = n[f, 0] * toward[0] + n[f, 1] * toward[1] + n[f, 2] * toward[2]
    first, stop = (near[f], near[f + 1]) if near.shape[0] > 0 else (0, n.shape[0])
    for s in range(origins.shape[0]):
        o, w, length = origins[s], dirs[s], lengths[s]
        alpha = (c[f] - (n[f, 0] * o[0] + n[f, 1] * o[1] + n[f, 2] * o[2])) / q
        beta = -(n[f, 0] * w[0] + n[f, 1] * w[1] + n[f, 2] * w[2]) / q
        ry = math.sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]) + length + max(alpha, alpha + beta * length, 0.0)
        plane = dplanes[1] + math.sqrt(3.0) * dplanes[0] * ry + ry * du
        lo, hi, lo_a, lo_b, hi_a, hi_b = 0.0, length, 0.0, 0.0, length, length
        for i in range(first, stop):
            g = near[i] if near.shape[0] > 0 else i
            qg = n[g, 0] * toward[0] + n[g, 1] * toward[1] + n[g, 2] * toward[2]
            if g == f or not qg > 0.0:
                continue
            a = c[g] - (n[g, 0] * o[0] + n[g, 1] * o[1] + n[g, 2] * o[2]) - alpha * qg
            b = -(n[g, 0] * w[0] + n[g, 1] * w[1] + n[g, 2] * w[2]) - beta * qg
            e = (plane + 16.0 * EPS * (abs(c[g]) + abs(c[f]) + 2.0 * ry)) * (1.0 + qg / q)
            if b == 0.0:  # h_g constant: the beam lights all or nothing, unknown which where |a| < e
                if a < 0.0:
                    hi = -math.inf
                if abs(a) < e:
                    lo_b, hi_a = length, 0.0
                continue
            t0, t1, t2 = -a / b, (-e - a) / b, (e - a) / b  # the true root lies between t1 and t2
            if b > 0.0:  # h_g >= 0 from its root on
                lo, lo_a, lo_b = max(lo, t0), max(lo_a, t1), max(lo_b, t2)
            else:  # up to its root (t2 < t1)
                hi, hi_a, hi_b = min(hi, t0), min(hi_a, t2), min(hi_b, t1)
        r = out[s]
        r[0], r[1] = lo, max(hi, lo)
        r[2], r[3] = min(max(lo_a, 0.0), length), min(max(lo_b, 0.0), length)
        r[4], r[5] = min(max(hi_a, 0.0), length), min(max(hi_b, 0.0), length)
        r[6], r[7] = alpha, beta
        r[8] = (plane + 16.0 * EPS * (abs(c[f]) + ry)) / q


@njit
def beams_closed(rows, toward, dirs, kt, ks, code, g, out, edges):
    """out (N, C) = ks Phi ∫ exp(-kt (t + s_f(t))) dt over each segment's lit interval of one beam
    (rows: `beam_intervals`' out; Phi the phase value at toward·w), by (3) on the line (1) of face f, and
    edges (N, C) = a bound on what the interval's ends, misplaced within their spans, change: ks Phi
    times each span's length times the integrand's largest value on it, exp(-kt (g_min - es)) (g = t +
    max(s_f, 0) >= t and >= t + s_f, linear: g_min from the span's ends; es s_f's error)."""
    out[:] = 0.0
    for s in range(rows.shape[0]):
        r, w = rows[s], dirs[s]
        ph = phase_value(code, g, toward[0] * w[0] + toward[1] * w[1] + toward[2] * w[2])
        if r[1] > r[0]:
            _accumulate(kt, ks, ph, r[0], r[1], r[6], r[7], out[s])
            for ch in range(kt.shape[0]):
                if kt[ch] == 0.0:
                    out[s, ch] += ks[ch] * ph * (r[1] - r[0])
        for ch in range(kt.shape[0]):
            e = 0.0
            for a, b in ((r[2], min(r[3], r[5])), (max(r[4], r[2]), r[5])):  # both intervals lie in [lo_a, hi_b]
                if b > a:
                    g_min = max(a, min(a + r[6] + r[7] * a, b + r[6] + r[7] * b)) - r[8]
                    e += (b - a) * math.exp(-kt[ch] * max(g_min, 0.0))
            edges[s, ch] = ks[ch] * ph * e


@njit
def segment_radiance(n, c, o, w, toward, length, kt, ks, phase, out, alpha, beta, cuts, lines, only=-1):
    """Eq. (2) per unit irradiance for one segment (o, unit w, length T <= inf) and every channel
    (kt, ks, out: (C,)), the light toward `toward` (unit), Phi = `phase`; alpha, beta, cuts, lines:
    `envelope`'s scratch; `only`: see `_pieces`. False (out untouched) for more than MAX_FACES faces."""
    if n.shape[0] > MAX_FACES:
        return False
    _pieces(n, c, o, w, toward, length, kt, ks, phase, out, alpha, beta, cuts, lines, only)
    return True


@njit
def segments_bounded(n, c, origins, dirs, lengths, toward, kt, ks, code, g, out, bound, only=-1):
    """`segment_radiance` of N segments (origins, dirs (N, 3), lengths (N,)) into out (N, C), with the
    phase function (code, g) at each segment's scattering cosine
    toward·w, and a bound on each value's error (N, C): (KERNEL_FLOOR + 8 eps kt max_f (|c_f| + |o| +
    T) / q_f) x value, the maximum over the faces of the segment's envelope (the docstring's accuracy,
    1e-12 at worst, and the condition of eq. (2) in its inputs where a face the light grazes
    magnifies the rounding of c_f - n_f·p by 1 / q_f; tests/test_convex_directional.py); 0 where the
    value is 0 (no light, or exp(-kt g) below the smallest double); `only`: see `_pieces`. False
    (nothing written) for more than MAX_FACES faces."""
    if n.shape[0] > MAX_FACES:
        return False
    nf = n.shape[0]
    alpha, beta = np.empty(nf), np.empty(nf)
    cuts, lines = np.empty(nf + 1), np.empty(nf, dtype=np.int64)
    for s in range(origins.shape[0]):
        o, w, length = origins[s], dirs[s], lengths[s]
        # the scattering cosine: the light travels along -toward, the eye is along -w
        mu = toward[0] * w[0] + toward[1] * w[1] + toward[2] * w[2]
        m = _pieces(n, c, o, w, toward, length, kt, ks, phase_value(code, g, mu), out[s], alpha, beta, cuts, lines,
                    only)
        scale = 0.0
        norm_o = math.sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2])
        for i in range(m):
            f = lines[i]
            if only >= 0 and f != only:
                continue
            q = n[f, 0] * toward[0] + n[f, 1] * toward[1] + n[f, 2] * toward[2]
            scale = max(scale, (abs(c[f]) + norm_o + length) / q)
        for ch in range(kt.shape[0]):
            v = out[s, ch]
            cond = 8.0 * EPS * kt[ch] * scale if kt[ch] > 0.0 else 0.0
            bound[s, ch] = (KERNEL_FLOOR + cond) * v if v > 0.0 else 0.0
    return True
