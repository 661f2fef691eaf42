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

The circles the horizon cuts have no such bound: their order climbs ORDERS until RUN consecutive pairs
of orders (three successive orders) agree to SHARE x the tolerance relative to the finer in every
channel, the finest of them kept; where none do, the finest of the ladder is kept and the point counted
(as where no order of ORDERS meets the bound of the circles above the horizon).
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


def _tables():
    """(nodes, weights, offsets) of ORDERS' rules on [0, 1], concatenated; order i at offsets[i]:offsets[i + 1]."""
    rules = [gauss_legendre(n) for n in ORDERS]
    offsets = np.cumsum([0] + [len(x) for x, _ in rules]).astype(np.int64)
    return np.concatenate([x for x, _ in rules]), np.concatenate([w for _, w in rules]), offsets


NODES, WEIGHTS, OFFSETS = _tables()


def irradiance(centre, radius: float, radiance, points, normals, sigma_t, tol=None, missed=None):
    """(M, 3) the unshadowed irradiance L int max(0, n·w) T dw of the sphere (`centre`, `radius`,
    radiance L (3,)) at points outside it with unit normals n, through a homogeneous medium of
    extinction `sigma_t` (3,) (0: the vacuum), to the relative tolerance `tol` (None: TOL). Points on
    or inside the sphere get 0 (not lit from outside). `missed` (1,), if given: += the points where no
    three successive orders of ORDERS agreed or none met the bound (the finest kept; module docstring)."""
    out = np.zeros((len(points), 3))
    missed = np.zeros(1) if missed is None else missed
    _irradiance(np.asarray(centre, float), float(radius), np.ascontiguousarray(points, float),
                np.ascontiguousarray(normals, float), np.ascontiguousarray(sigma_t, float),
                SHARE * (TOL if tol is None else float(tol)), NODES, WEIGHTS, OFFSETS, out, missed)
    return out * np.asarray(radiance, float)[None, :]


def cap_cosine(centre, radius: float, points, normals):
    """(M,) n·a - sin alpha: >= 0 where the whole cap the sphere fills lies above the plane of the
    normal n at each point (the point outside the sphere); negative elsewhere."""
    rel = np.asarray(centre, float)[None, :] - points
    d = np.linalg.norm(rel, axis=1)
    safe = np.where(d > radius, d, 1.0)
    return np.where(d > radius, np.einsum("ij,ij->i", normals, rel) / safe - radius / safe, -np.inf)


@njit
def _irradiance(centre, R, points, normals, kt, tol, nodes, weights, offsets, out, missed):
    """`irradiance` / L into out (M, 3); missed[0] += the points where no RUN consecutive pairs of orders
    agreed or no order met the bound (`_above`)."""
    prev, exact = np.empty(3), np.empty(3)
    for i in range(points.shape[0]):
        cos_t, sin_t, sin_a, cos_a, root_k, u0, ustar, eta = _geometry(centre, R, points[i], normals[i])
        if not cos_t > -sin_a:  # on or inside the sphere, or the cap wholly below the horizon
            continue
        whole = cos_t > 0.0 and u0 > ustar  # the circles [u*, u0] wholly above the horizon
        vacuum = math.pi * cos_t * (cos_t * cos_t if ustar > 0.0 else sin_a * sin_a) if whole else 0.0
        bounded = True
        for c in range(3):
            exact[c] = vacuum
            if c > 0 and kt[c] == kt[c - 1]:  # a grey medium: the channel before's
                exact[c] = exact[c - 1]
            elif kt[c] != 0.0 and whole:
                exact[c], ok = _above(kt[c], cos_t, cos_a, root_k, ustar, u0, tol, nodes, weights, offsets)
                bounded = bounded and ok
            out[i, c] = exact[c]
        geometry = (cos_t, sin_t, cos_a, root_k, ustar, u0, eta)
        if ustar > 0.0 and not _ladder(out[i], prev, exact, nodes, weights, offsets, tol, kt, geometry):
            bounded = False
        if not bounded:
            missed[0] += 1.0


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
    alpha int cosh u sinh u exp(-kt sqrt(d^2 - R^2) e^-u) du, whether within tol of it) by the coarsest
    of ORDERS with at least the nodes `_needed` for a remainder of tol x a lower bound of the integral
    (`_above_rule`'s, of the coarsest); the finest of ORDERS where none has."""
    scale = 2.0 * math.pi * cos_t * cos_a * cos_a
    span = u0 - ustar
    first, least = _above_rule(kt, root_k, ustar, span, nodes[offsets[0]:offsets[1]], weights[offsets[0]:offsets[1]])
    need = _needed(kt, root_k, ustar, u0, math.log(tol * least)) if least > 0.0 else math.inf
    for k in range(len(offsets) - 1):
        lo, hi = offsets[k], offsets[k + 1]
        if hi - lo >= need or k == len(offsets) - 2:
            value = first if k == 0 else _above_rule(kt, root_k, ustar, span, nodes[lo:hi], weights[lo:hi])[0]
            return scale * value, hi - lo >= need
    return 0.0, False


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
