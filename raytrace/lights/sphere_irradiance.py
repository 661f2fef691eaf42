"""The unshadowed irradiance of a Lambertian sphere emitter at surface points in a homogeneous
medium (or the vacuum): a 1-D rule in the cap's polar angle, the azimuth in closed form
(docs/area_lights.md, "Surfaces lit by a sphere").

From a point x at distance d > R of the centre c, the sphere fills the cap of half-angle alpha
(sin alpha = R / d) about the axis a = (c - x) / d. A direction w at polar angle beta about a meets
the sphere at the distance s(beta) = d cos beta - sqrt(R^2 - d^2 sin^2 beta), so the transmittance
exp(-kt s) depends on beta alone and the radiance L is constant: with theta the angle between the
normal n and a, A = cos theta cos beta, B = sin theta sin beta,

    E = L int_0^alpha exp(-kt s(beta)) Phi(beta) sin beta dbeta,  Phi = int_0^2pi max(0, A + B cos phi) dphi,

Phi = 2 pi max(A, 0) where |A| >= B (the circle of directions at beta wholly above or below the
horizon), else 2 (psi A + sqrt(B^2 - A^2)), psi = acos(-A / B). Since B^2 - A^2 = sin^2 theta -
cos^2 beta, psi = atan2(sqrt(sin^2 theta - cos^2 beta), -A): Phi has one branch point, where the
horizon starts cutting the circles (cos beta = sin theta, beta* = |pi/2 - theta|).

The variable is u, cos beta = cos alpha cosh u (u from 0 at the cap's edge to u0 = atanh(sin alpha)
on the axis): then sin beta dbeta = cos alpha sinh u du and s = sqrt(d^2 - R^2) e^-u, entire in u,
where in beta the square root of s has branch points at the cap's edge and at pi - alpha (which
closes on it as d nears R). So the integrand is entire but for Phi's branch point u*: two pieces,
[0, u*] (the circles the horizon cuts) with u = u* - w^2 (the square root's half powers become
integer ones), and [u*, u0] (wholly above the horizon: 2 pi A, or below: 0), each Gauss–Legendre.
In the vacuum the second is exact: pi cos theta sin^2 alpha where the horizon cuts no circle, else
pi cos^3 theta (the cap of half-angle pi/2 - theta about a, which lies above the horizon). In a medium
its integrand is entire, and its rule's order is the coarsest of ORDERS whose remainder bound (on a
Bernstein ellipse, `_needed`) is within the tolerance of a lower bound of the piece: a bound, not an
agreement, so a point whose cap lies wholly above its horizon has its irradiance within the tolerance.

Phi on [0, u*] is also singular on the axis, where B = 0 (psi's logarithm, weighted by A): at
w = i eta, eta^2 = u0 - u*, which nears the piece's end w = 0 where the horizon cuts the cap near its
middle (theta near pi/2). A rule in w resolves it slowly, and low orders blind to it agree with each
other (two successive orders agreed to a quarter of the tolerance, both 2x the tolerance off). Where
KAPPA sqrt(u*) < eta < SPLIT sqrt(u*) the piece splits at SPLIT sqrt(u*): toward w = 0 in t,
w = eta sinh t (the sinh transformation of Johnston and Elliott, 2005: the singularity at t = i pi/2,
a fixed distance from an interval that grows as log(sqrt(u*) / eta)), the rest in w. Below
KAPPA sqrt(u*) what the singularity shapes weighs about (eta / sqrt(u*))^3 of the irradiance (measured
2e-14 at 1e-5) and stays in w.

Asked for a bound, the circles the horizon cuts take the coarsest of ORDERS whose remainder bound is
within half the tolerance of the value in every channel (`_bounded_cut`): on Bernstein ellipses of the
rule's variable (w, or t in the split's first piece) the integrand's analytic continuation is bounded
factor by factor (`_arc_bound`) on CUT_ARCS arcs of each ellipse that avoids its singularities
(w = +-i eta, the axis; w^2 = 2 u* and u* + u0 on the real axis), so that where one holds the point's
error is proven (the `bound` of `irradiance`). Otherwise, or where none does (the axis within about
KAPPA sqrt(u*) of the piece's end: no ellipse clears it; or the bound needs more than the finest
order), the order climbs ORDERS until RUN consecutive pairs of orders (three successive orders) agree
to SHARE x the tolerance relative to the finer in every channel, the finest of them kept, and the bound
is inf; where none do, the finest of the ladder is kept and the point counted (as where no order of
ORDERS meets the bound of the circles above the horizon).
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .area import gauss_legendre

ORDERS = (4, 6, 8, 12, 16, 24, 32, 48, 64)  # Gauss–Legendre nodes per piece, climbed in turn
SHARE = 0.25  # the share of the tolerance two orders must agree to (as the emitters' cubature: cubature.py)
TOL = 1e-10  # the tolerance where the method gives none
SERIES, TERMS = 0.125, 9  # t - atan t by its series below t = SERIES (TERMS terms: the next, t^21 / 21, is below 1e-17 t^3 / 3)
KAPPA = 1e-6  # eta / sqrt(u*) below which the axis's singularity is left to the rule in w (module docstring)
SPLIT = 0.25  # where [0, sqrt(u*)] splits, and the eta / sqrt(u*) below which it does (module docstring)
RUN = 2  # the consecutive pairs of orders that must agree (two orders agreeing is not a bound)
FLOOR = 1e-300  # agreement below this absolute irradiance / L counts as exact (a cap that vanishes)
RHO, RHOS = 2.0 ** 0.5, 40  # the Bernstein ellipses tried for the remainder bound (`_needed`): rho = RHO^j
CUT_RHO, CUT_RHOS, CUT_ARCS = 2.0 ** 0.25, 24, 8  # the same for the circles the horizon cuts (`_cut_ellipses`)


def _tables():
    """(nodes, weights, offsets) of ORDERS' rules on [0, 1], concatenated; order i at offsets[i]:offsets[i + 1]."""
    rules = [gauss_legendre(n) for n in ORDERS]
    offsets = np.cumsum([0] + [len(x) for x, _ in rules]).astype(np.int64)
    return np.concatenate([x for x, _ in rules]), np.concatenate([w for _, w in rules]), offsets


NODES, WEIGHTS, OFFSETS = _tables()


def irradiance(centre, radius: float, radiance, points, normals, sigma_t, tol=None, missed=None, bound=None):
    """(M, 3) the unshadowed irradiance L int max(0, n·w) T dw of the sphere (`centre`, `radius`,
    radiance L (3,)) at points outside it with unit normals n, through a homogeneous medium of
    extinction `sigma_t` (3,) (0: the vacuum), to the relative tolerance `tol` (None: TOL). Points on
    or inside the sphere get 0 (not lit from outside). `missed` (1,), if given: += the points where no
    three successive orders of ORDERS agreed or none met the bound (the finest kept; module docstring).
    `bound` (M, 3), if given: a proven bound of each value's error (the rule's; rounding aside), inf
    where the circles the horizon cuts stopped on agreement; only then do those circles take the order
    of their bound (`_bounded_cut`; without it their agreement, which costs a few times less)."""
    out = np.zeros((len(points), 3))
    missed = np.zeros(1) if missed is None else missed
    errors = np.zeros((len(points), 3))
    _irradiance(np.asarray(centre, float), float(radius), np.ascontiguousarray(points, float),
                np.ascontiguousarray(normals, float), np.ascontiguousarray(sigma_t, float),
                SHARE * (TOL if tol is None else float(tol)), NODES, WEIGHTS, OFFSETS, out, missed, errors,
                bound is not None)
    if bound is not None:
        bound[...] = errors * np.abs(np.asarray(radiance, float))[None, :]
    return out * np.asarray(radiance, float)[None, :]


def cap_cosine(centre, radius: float, points, normals):
    """(M,) n·a - sin alpha: >= 0 where the whole cap the sphere fills lies above the plane of the
    normal n at each point (the point outside the sphere); negative elsewhere."""
    rel = np.asarray(centre, float)[None, :] - points
    d = np.linalg.norm(rel, axis=1)
    safe = np.where(d > radius, d, 1.0)
    return np.where(d > radius, np.einsum("ij,ij->i", normals, rel) / safe - radius / safe, -np.inf)


@njit
def _irradiance(centre, R, points, normals, kt, tol, nodes, weights, offsets, out, missed, errors, prove):
    """`irradiance` / L into out (M, 3) and its error bounds into errors (M, 3), the circles the horizon cuts
    by their bound where `prove` and it holds; missed[0] += the points where no RUN consecutive pairs of
    orders agreed or no order met the bound (`_above`)."""
    prev, exact = np.empty(3), np.empty(3)
    base, damp = np.empty((2, CUT_RHOS)), np.empty((2, CUT_RHOS))
    for i in range(points.shape[0]):
        cos_t, sin_t, sin_a, cos_a, root_k, u0, ustar, eta = _geometry(centre, R, points[i], normals[i])
        if not cos_t > -sin_a:  # on or inside the sphere, or the cap wholly below the horizon
            continue
        whole = cos_t > 0.0 and u0 > ustar  # the circles [u*, u0] wholly above the horizon
        vacuum = math.pi * cos_t * (cos_t * cos_t if ustar > 0.0 else sin_a * sin_a) if whole else 0.0
        bounded = True
        for c in range(3):
            exact[c], errors[i, c] = vacuum, 0.0
            if c > 0 and kt[c] == kt[c - 1]:  # a grey medium: the channel before's
                exact[c], errors[i, c] = exact[c - 1], errors[i, c - 1]
            elif kt[c] != 0.0 and whole:
                exact[c], errors[i, c] = _above(kt[c], cos_t, cos_a, root_k, ustar, u0, tol, nodes, weights, offsets)
                bounded = bounded and errors[i, c] < math.inf
            out[i, c] = exact[c]
        geometry = (cos_t, sin_t, cos_a, root_k, ustar, u0, eta)
        if ustar > 0.0 and not (prove and _bounded_cut(out[i], errors[i], exact, nodes, weights, offsets, tol, kt,
                                                       geometry, base, damp)):
            for c in range(3):
                errors[i, c] = math.inf
            if not _ladder(out[i], prev, exact, nodes, weights, offsets, tol, kt, geometry):
                bounded = False
        if not bounded:
            missed[0] += 1.0


@njit
def _bounded_cut(acc, errors, exact, nodes, weights, offsets, tol, kt, geometry, base, damp):
    """acc (3,) = `exact` (3,) + the circles the horizon cuts (`_add_cut_pieces`) by the coarsest order of
    ORDERS whose remainder bound (`_cut_ellipses`, summed over the pieces) is within half tol of the
    value in every channel, errors (3,) += that bound (True); False where none is (acc then undefined).
    The order tried first is the coarsest whose bound is within tol / 4 of the 4-node value; then up the
    ladder from there until one's bound holds of its own value."""
    cos_t, sin_t, cos_a, root_k, ustar, u0, eta = geometry
    top = math.sqrt(ustar)
    split = KAPPA * top < eta < SPLIT * top
    counts = (_cut_ellipses(cos_t, sin_t, cos_a, ustar, u0, eta, 0.0, SPLIT * top if split else top, split,
                            base[0], damp[0]),
              _cut_ellipses(cos_t, sin_t, cos_a, ustar, u0, eta, SPLIT * top, top, False, base[1], damp[1])
              if split else 0)
    if counts[0] == 0 or (split and counts[1] == 0):
        return False
    k = 0
    while k < len(offsets) - 1:
        lo, hi = offsets[k], offsets[k + 1]
        for c in range(3):
            acc[c] = exact[c]
        _add_cut_pieces(acc, nodes[lo:hi], weights[lo:hi], kt, *geometry)
        if _within(base, damp, counts, split, kt, root_k, hi - lo, 0.5 * tol * acc):
            for c in range(3):
                errors[c] += _summed(base, damp, counts, split, kt[c] * root_k, hi - lo)
            return True
        if k == 0:  # on to the coarsest order whose bound is within tol / 4 of this value
            k += 1
            while k < len(offsets) - 2 and not _within(base, damp, counts, split, kt, root_k,
                                                         offsets[k + 1] - offsets[k], 0.25 * tol * acc):
                k += 1
        else:
            k += 1
    return False


@njit
def _summed(base, damp, counts, split, kappa, n):
    """The remainder bound of n nodes a piece summed over the pieces (`_cut_ellipses`' tables)."""
    return _cut_bound(base[0], damp[0], counts[0], kappa, n) + \
        (_cut_bound(base[1], damp[1], counts[1], kappa, n) if split else 0.0)


@njit
def _within(base, damp, counts, split, kt, root_k, n, limit):
    """Whether the summed remainder bound of n nodes a piece is within limit (3,) in every channel."""
    for c in range(3):
        if not _summed(base, damp, counts, split, kt[c] * root_k, n) <= limit[c]:
            return False
    return True


@njit
def _ladder(acc, prev, exact, nodes, weights, offsets, tol, kt, geometry):
    """acc (3,) = `exact` (3,) (the circles wholly above the horizon) + the circles the horizon cuts
    (`_add_cut_pieces` of `geometry`) by ORDERS in turn, until RUN consecutive pairs of orders agree to tol
    relative to the finer (True; the finest of them kept) or the finest (False); prev (3,) scratch."""
    run = 0
    for k in range(len(offsets) - 1):
        for c in range(3):
            acc[c] = exact[c]
        lo, hi = offsets[k], offsets[k + 1]
        _add_cut_pieces(acc, nodes[lo:hi], weights[lo:hi], kt, *geometry)
        if k > 0:
            agree = True
            for c in range(3):
                agree = agree and abs(acc[c] - prev[c]) <= tol * abs(acc[c]) + FLOOR
            run = run + 1 if agree else 0
            if run == RUN:
                return True
        for c in range(3):
            prev[c] = acc[c]
    return False


@njit
def _geometry(centre, R, x, n):
    """(cos theta, sin theta, sin alpha, cos alpha, sqrt(d^2 - R^2), u0, u*, eta) of the point x with
    normal n (module docstring); cos theta -inf where x is on or inside the sphere."""
    ax, ay, az = centre[0] - x[0], centre[1] - x[1], centre[2] - x[2]
    d = math.sqrt(ax * ax + ay * ay + az * az)
    if not d > R:
        return -math.inf, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0
    ax, ay, az = ax / d, ay / d, az / d
    cos_t = n[0] * ax + n[1] * ay + n[2] * az
    cx, cy, cz = n[1] * az - n[2] * ay, n[2] * ax - n[0] * az, n[0] * ay - n[1] * ax
    sin_t = math.sqrt(cx * cx + cy * cy + cz * cz)  # |n x a|: accurate where theta is small
    sin_a = R / d
    root_k = math.sqrt((d - R) * (d + R))  # sqrt(d^2 - R^2)
    cos_a = root_k / d
    u0 = 0.5 * math.log1p(2.0 * R / (d - R))  # atanh(sin alpha), with cos alpha cosh u0 = 1 as root_k rounds
    # u*: where cos beta = sin theta, cosh u* = 1 + eps (0 where the horizon cuts no circle of the
    # cap); eps from sin^2 theta - cos^2 alpha = (sin alpha - cos theta)(sin alpha + cos theta), without
    # the cancellation of sin theta / cos alpha - 1 where the horizon grazes the cap's edge
    eps = (sin_a - cos_t) * (sin_a + cos_t) / ((sin_t + cos_a) * cos_a)
    if not eps > 0.0:
        return cos_t, sin_t, sin_a, cos_a, root_k, u0, 0.0, 0.0
    ustar = min(math.log1p(eps + math.sqrt(eps * (2.0 + eps))), u0)
    # eta^2 = u0 - u*: sinh((u0 - u*) / 2) = (cosh u0 - cosh u*) / (2 sinh((u0 + u*) / 2)), and cosh u0 -
    # cosh u* = (1 - sin theta) / cos alpha = cos^2 theta / ((1 + sin theta) cos alpha), without the cancellation
    near = cos_t * cos_t / ((1.0 + sin_t) * cos_a * 2.0 * math.sinh(0.5 * (u0 + ustar)))
    return cos_t, sin_t, sin_a, cos_a, root_k, u0, ustar, math.sqrt(2.0 * math.asinh(near))


@njit
def _add_cut_pieces(acc, x, wx, kt, cos_t, sin_t, cos_a, root_k, ustar, u0, eta):
    """acc (3,) += the integral in u (module docstring) over the circles the horizon cuts, [0, u*] (in two
    where KAPPA < eta / sqrt(u*) < SPLIT), u = u* - w^2, w in [0, sqrt(u*)], du = 2 w dw, by the
    Gauss–Legendre rule (x, wx) on [0, 1] in each piece."""
    top = math.sqrt(ustar)
    if KAPPA * top < eta < SPLIT * top:
        _add_cut(acc, x, wx, kt, cos_t, sin_t, cos_a, root_k, ustar, 0.0, SPLIT * top, eta)
        _add_cut(acc, x, wx, kt, cos_t, sin_t, cos_a, root_k, ustar, SPLIT * top, top, 0.0)
    else:
        _add_cut(acc, x, wx, kt, cos_t, sin_t, cos_a, root_k, ustar, 0.0, top, 0.0)


@njit
def _above(kt, cos_t, cos_a, root_k, ustar, u0, tol, nodes, weights, offsets):
    """(the circles wholly above the horizon, [u*, u0], through extinction kt > 0: 2 pi cos theta cos^2
    alpha int cosh u sinh u exp(-kt sqrt(d^2 - R^2) e^-u) du, a bound of its error: tol x a lower bound of
    the integral, inf where no order has it) by the coarsest of ORDERS with at least the nodes `_needed`
    for a remainder of tol x that lower bound (`_above_rule`'s, of the coarsest); the finest of ORDERS
    where none has."""
    scale = 2.0 * math.pi * cos_t * cos_a * cos_a
    span = u0 - ustar
    first, least = _above_rule(kt, root_k, ustar, span, nodes[offsets[0]:offsets[1]], weights[offsets[0]:offsets[1]])
    need = _needed(kt, root_k, ustar, u0, math.log(tol * least)) if least > 0.0 else math.inf
    for k in range(len(offsets) - 1):
        lo, hi = offsets[k], offsets[k + 1]
        if hi - lo >= need or k == len(offsets) - 2:
            value = first if k == 0 else _above_rule(kt, root_k, ustar, span, nodes[lo:hi], weights[lo:hi])[0]
            return scale * value, scale * tol * least if hi - lo >= need else math.inf
    return 0.0, math.inf


@njit
def _above_rule(kt, root_k, ustar, span, x, wx):
    """(int_{u*}^{u* + span} g(u) du, g = cosh u sinh u exp(-kt root_k e^-u), by the Gauss–Legendre rule
    (x, wx) on [0, 1] (ascending nodes); a lower bound of it: g grows with u, so the sum of g at each node
    times the step to the next (the last to the end) is at most the integral)."""
    total, lower = 0.0, 0.0
    for j in range(x.shape[0]):
        u = ustar + span * x[j]
        g = math.cosh(u) * math.sinh(u) * math.exp(-kt * root_k * math.exp(-u))
        total += g * wx[j]
        lower += g * ((x[j + 1] if j + 1 < x.shape[0] else 1.0) - x[j])
    return total * span, lower * span


@njit
def _needed(kt, root_k, ustar, u0, target):
    """The fewest nodes n of `_above_rule` whose remainder bound is at most exp(target): with u = c + h z
    (z in [-1, 1]) the integrand g is entire and, on the Bernstein ellipse E_rho (|Re z| <= (rho + 1 / rho)
    / 2 = p, |Im z| <= (rho - 1 / rho) / 2 = q), |g| <= M = cosh(2 (c + h p)) / 2 exp(-kt root_k e^-(c + h p)
    cos(h q)) where h q < pi / 2 (|sinh 2u| <= cosh 2 Re u; Re(-kt root_k e^-u) = -kt root_k e^-Re u cos
    Im u), so |I - I_n| <= h 64 / 15 M rho^(2 - 2n) / (rho^2 - 1) (Trefethen, Approximation Theory and
    Approximation Practice, Theorem 19.3, whose rule of n + 1 points has rho^-2n); the least n over
    rho = RHO^j, j = 1 ... RHOS (inf where none: the bound needs h q < pi / 2)."""
    c, h = 0.5 * (ustar + u0), 0.5 * (u0 - ustar)
    best = math.inf
    for j in range(1, RHOS + 1):
        rho = RHO ** j
        p, q = 0.5 * (rho + 1.0 / rho), 0.5 * (rho - 1.0 / rho)
        if not h * q < 0.5 * math.pi:
            break
        x = 2.0 * (c + h * p)
        log_m = x + math.log1p(math.exp(-2.0 * x)) - 2.0 * math.log(2.0) - kt * root_k * math.exp(-(c + h * p)) * \
            math.cos(h * q)
        log_b = math.log(h * 64.0 / 15.0) + log_m - math.log(rho * rho - 1.0)  # the bound is exp(log_b) rho^(2 - 2n)
        best = min(best, 1.0 + max(log_b - target, 0.0) / (2.0 * j * math.log(RHO)))
    return best


@njit
def _cut_ellipses(cos_t, sin_t, cos_a, ustar, u0, eta, lo, hi, sinh_t, base, damp):
    """The remainder bounds of the rule for the circles the horizon cuts on [lo, hi] in w or (sinh_t) in t,
    w = eta sinh t (`_add_cut`), on the Bernstein ellipses rho = CUT_RHO^(j + 1) of that variable v
    (v = m + h z): |I - I_n| <= exp(base[j] - kt root_k damp[j]) rho^(2 - 2n) (Trefethen, Theorem 19.3, as
    `_needed`) for j below the count returned (the ellipses that avoid the singularities). The bound of
    the integrand on an ellipse is the largest of `_arc_bound`'s over CUT_ARCS arcs of its upper half (the
    integrand is real on the real axis: |G| is symmetric)."""
    v0, v1 = (math.asinh(lo / eta), math.asinh(hi / eta)) if sinh_t else (lo, hi)
    m, h = 0.5 * (v0 + v1), 0.5 * (v1 - v0)
    for j in range(CUT_RHOS):
        rho = CUT_RHO ** (j + 1)
        p, q = 0.5 * (rho + 1.0 / rho), 0.5 * (rho - 1.0 / rho)
        log_m, damp[j] = -math.inf, math.inf
        for k in range(CUT_ARCS):
            f0, f1 = math.pi * k / CUT_ARCS, math.pi * (k + 1) / CUT_ARCS
            y = q * (1.0 if f0 <= 0.5 * math.pi <= f1 else max(math.sin(f0), math.sin(f1)))
            x0, x1 = m + h * p * math.cos(f1), m + h * p * math.cos(f0)
            a_lo, a_hi = (0.0 if x0 <= 0.0 <= x1 else min(abs(x0), abs(x1))), max(abs(x0), abs(x1))
            arc, arc_damp = _arc_bound(cos_t, sin_t, cos_a, ustar, u0, eta, sinh_t, a_lo, a_hi, h * y)
            if arc == math.inf:
                return j
            log_m, damp[j] = max(log_m, arc), min(damp[j], arc_damp)
        base[j] = math.log(h * 64.0 / 15.0 / (rho * rho - 1.0)) + log_m
    return CUT_RHOS


@njit
def _arc_bound(cos_t, sin_t, cos_a, ustar, u0, eta, sinh_t, a_lo, a_hi, b):
    """(log M, D): |G| <= M exp(-kt root_k D) for v = a + i b', a_lo <= |a| <= a_hi, 0 <= b' <= b, and on
    the segments from those points down to the real axis (log M inf where that rectangle may hold a
    singularity). G = Phi cos alpha sinh u 2 w exp(-kt root_k e^-u) dw/dv; with s = w^2 (u = u* - s)
    bounded by Re s in [s_lo, s_hi], |Im s| <= s_im, factor by factor: |sinh u|, |cosh u| <= cosh Re u;
    |A| <= |cos theta| C, |R| <= sin theta + C (C = cos alpha max cosh Re u); |exp(-kt root_k e^-u)| <=
    exp(-kt root_k e^-Re u cos Im u) (|Im u| <= pi / 2); Phi = 2 (A psi + R) with |psi| <= 2 pi + b max
    |dpsi/dv| (on the real axis psi is in [0, pi] for w > 0 and, R being odd in w, in [-pi, 2 pi] for
    w < 0), dpsi/dw = -2 cos theta cos alpha sinh u / ((1 - c^2) S), R = w S, c = cos beta = cos alpha
    cosh u, from lower bounds of |sinh|, |cosh| (|sinh(x + iy)| >= sinh |x|, |cosh(x + iy)| >= max(sinh
    |x|, cos y)) in 1 - c = 2 cos alpha sinh((u0 + u) / 2) sinh((eta^2 + s) / 2), |1 + c| >= 1 (Re c >= 0),
    S^2 = cos alpha sinh(u* - s / 2) (sinh(s / 2) / (s / 2)) (sin theta + c), sin theta + c = 2 cos alpha
    cosh(u* - s / 2) cosh(s / 2), |sinh z / z| >= 2 - sinh |z| / |z|. The rectangle must keep |Im s| <=
    pi / 2, s_hi below 2 u* and u* + u0 (branch points of S and of 1 - c on the real axis), eta^2 + s_lo > 0
    (the axis: w = +-i eta) and, in t (w = eta sinh t), b < pi / 4."""
    e2 = eta * eta
    if sinh_t:
        if not b < 0.25 * math.pi:
            return math.inf, 0.0
        s_lo, s_hi = 0.5 * e2 * (math.cosh(2.0 * a_lo) * math.cos(2.0 * b) - 1.0), e2 * math.sinh(a_hi) ** 2
        s_im, jac = 0.5 * e2 * math.sinh(2.0 * a_hi) * math.sin(2.0 * b), eta * math.cosh(a_hi)
    else:
        s_lo, s_hi, s_im, jac = a_lo * a_lo - b * b, a_hi * a_hi, 2.0 * a_hi * b, 1.0
    if not (s_im <= 0.5 * math.pi and s_hi < 2.0 * ustar and s_hi < ustar + u0 and e2 + s_lo > 0.0):
        return math.inf, 0.0
    ch = math.cosh(max(abs(ustar - s_hi), abs(ustar - s_lo)))
    big_c = cos_a * ch
    s_abs = math.hypot(max(abs(s_lo), abs(s_hi)), s_im)
    half, v, cb = ustar - 0.5 * s_hi, 0.5 * s_abs, math.cos(0.5 * s_im)
    ratio = 1.0 if v < 1e-8 else 2.0 - math.sinh(v) / v  # |sinh(s / 2) / (s / 2)| from below
    if s_lo > 0.0:
        ratio = max(ratio, math.sinh(0.5 * s_lo) / v)
    if not ratio > 0.0:
        return math.inf, 0.0
    sh = math.sinh(half)
    s2 = cos_a * sh * ratio * 2.0 * cos_a * max(sh, cb) * cb  # |S|^2 from below
    minus = 2.0 * cos_a * math.sinh(0.5 * (u0 + ustar - s_hi)) * math.sinh(0.5 * (e2 + s_lo))  # |1 - c| from below
    dpsi = 2.0 * abs(cos_t) * cos_a * ch / (minus * math.sqrt(s2)) * jac
    phi = 2.0 * (abs(cos_t) * big_c * (2.0 * math.pi + b * dpsi) + sin_t + big_c)
    return math.log(phi * cos_a * ch * 2.0 * math.sqrt(s_abs) * jac), math.exp(-(ustar - s_lo)) * math.cos(s_im)


@njit
def _cut_bound(base, damp, count, kappa, n):
    """The least of the remainder bounds exp(base[j] - kappa damp[j]) rho_j^(2 - 2n) of `_cut_ellipses`
    (inf where none)."""
    best = math.inf
    for j in range(count):
        best = min(best, base[j] - kappa * damp[j] + (2.0 - 2.0 * n) * (j + 1) * math.log(CUT_RHO))
    return math.exp(best)


@njit
def _add_cut(acc, x, wx, kt, cos_t, sin_t, cos_a, root_k, ustar, lo, hi, eta):
    """acc (3,) += the circles the horizon cuts, u = u* - w^2 for w in [lo, hi], by the rule (x, wx) in w
    (eta 0) or in t, w = eta sinh t (eta > 0)."""
    t0 = math.asinh(lo / eta) if eta > 0.0 else lo
    span = (math.asinh(hi / eta) if eta > 0.0 else hi) - t0
    for j in range(x.shape[0]):
        t = t0 + span * x[j]
        w, dw = (eta * math.sinh(t), eta * math.cosh(t) * span) if eta > 0.0 else (t, span)
        u = ustar - w * w
        c = cos_a * math.cosh(u)  # cos beta
        # sin theta - cos beta = cos_a (cosh u* - cosh u), without the cancellation
        gap = 2.0 * cos_a * math.sinh(0.5 * (ustar + u)) * math.sinh(0.5 * w * w)
        root = math.sqrt(max(gap * (sin_t + c), 0.0))  # sqrt(B^2 - A^2)
        phi = _azimuths(cos_t * c, root)
        f = phi * cos_a * math.sinh(u) * 2.0 * w * dw * wx[j]
        _add_attenuated(acc, f, kt, root_k * math.exp(-u))


@njit
def _azimuths(a, root):
    """Phi = 2 (a psi + root), psi = atan2(root, -a), of a circle the horizon cuts (root = sqrt(B^2 - a^2)
    > 0); where a < 0 as 2 |a| (t - atan t), t = root / |a|, by its series where t is small (the two terms
    nearly cancel: the circle barely above the horizon)."""
    if a < 0.0 and root < SERIES * -a:
        t = root / -a
        t2, term, total = t * t, t * t * t, 0.0
        for k in range(1, TERMS + 1):
            total += term / (2 * k + 1) if k % 2 == 1 else -term / (2 * k + 1)
            term *= t2
        return -2.0 * a * total
    return 2.0 * (a * math.atan2(root, -a) + root)


@njit
def _add_attenuated(acc, f, kt, s):
    """acc (3,) += f exp(-kt s) per channel (exactly f where kt is 0)."""
    for c in range(3):
        acc[c] += f if kt[c] == 0.0 else f * math.exp(-kt[c] * s)
