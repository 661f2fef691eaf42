"""The exponential spherical atmosphere of "Sampling Analytic Participating Media" (the article
below): the Chapman function and the optical depth of a ray segment, in double precision, and its
inverse for free-path sampling (docs/optical_depth.md).

Density sigma0 exp(-(|p - c| - R)/H). A ray is given by the altitude ``h`` = |o - c| - R of its
origin and ``mu``, the cosine of its zenith angle there; t is the distance along the ray.

One exact representation serves everything (docs/optical_depth.md §2). With x = s/H the signed
distance from the periapsis (the ray's closest point to c, radius b), beta = b/H, and at a point of
the ray z = r/H, a = sqrt(z - beta) (so a = 0 at the periapsis and z cos^2 = a^2 (z + beta)),
the substitution w^2 = z - beta turns eq. 40 into

    int_{x_p}^{x_q} e^{Z - z(x)} dx = 2 e^{-h_p/H} int_0^{y_q} e^{-y(2 a_p + y)} f(a_p + y) dy,
    f(w) = (beta + w^2) / sqrt(2 beta + w^2),

for two points p, q on the same side of the periapsis (q farther from it), where
y(2 a_p + y) = (h - h_p)/H is the rise of the ray above p. The integrand is positive, bounded and
smooth, so no value is ever a difference of two Chapman functions; the Chapman function (eq. 42)
is the case y_q = inf, and the article's lower-hemisphere identity (eq. 48) becomes the split of a
segment at the periapsis into two such pieces, both with a_p = 0 (the C_h of eq. 47).

The rise is cut at u = 40 (the neglected tail is below e^{-40} f-weighted, < 1e-17 relative) and
integrated with 16-point Gauss-Legendre on u in [0, 10] and [10, 40] (mapped to y); measured
worst relative error 2e-15 for z >= 3 (docs/optical_depth.md §2.3).

Its error is bounded, not only measured (`remainder_bound`, docs/error_bounds.md "Atmospheres"):
the integrand is analytic inside Bernstein ellipses about each panel (entire but for the branch
points w = ±i sqrt(2 beta) of f), so the n-point rule is within (64/15) M rho^{-2n} / (rho^2 - 1)
times the half-width of the integral (Trefethen, Approximation Theory and Approximation Practice,
Thm 19.3), M the largest |integrand| on the ellipse of parameter rho, bounded in closed form; the
tail beyond u = 40 is below 2 e^{-40} (sqrt(beta) / (2 sqrt(a^2 + 40)) + 1/2). Over a grid of the
whole domain (scripts/bound_twins.py chapman) the relative bound is at most 8.9e-13 (at z = 3, the
smallest radius / scale height the atmosphere accepts) and 9.5e-16 for z >= 8.77; `REMAINDER`
holds 10 times those, for the columns' points (z >= radius / H), plus the rule's own rounding.
"""
import math

import numpy as np

from ..jit import njit

# 16-point Gauss-Legendre rule on [-1, 1]: the positive nodes and their weights
# (numpy.polynomial.legendre.leggauss(16)[:, 8:]; tests/test_optical_depth.py checks them).
_GL_X = (0.09501250983763744, 0.2816035507792589, 0.45801677765722737, 0.6178762444026438,
         0.755404408355003, 0.8656312023878318, 0.9445750230732326, 0.9894009349916499)
_GL_W = (0.18945061045506864, 0.18260341504492364, 0.16915651939500265, 0.1495959888165767,
         0.12462897125553407, 0.0951585116824926, 0.062253523938647456, 0.027152459411754176)

U_SPLIT = 10.0  # the rise (in scale heights) where the first panel ends
U_CUT = 40.0  # the rise beyond which the integrand (< e^{-40}) is dropped


@njit
def _y_of_rise(a, u):
    """y >= 0 with y (2a + y) = u, without cancellation."""
    if u <= 0.0:
        return 0.0
    return u / (math.sqrt(a * a + u) + a)


@njit
def _panel(a, beta, y0, y1):
    """int_{y0}^{y1} e^{-y(2a+y)} f(a+y) dy by the 16-point rule."""
    half = 0.5 * (y1 - y0)
    mid = 0.5 * (y0 + y1)
    acc = 0.0
    for k in range(8):
        for y in (mid - half * _GL_X[k], mid + half * _GL_X[k]):
            w2 = (a + y) * (a + y)
            acc += _GL_W[k] * math.exp(-y * (2.0 * a + y)) * (beta + w2) / math.sqrt(2.0 * beta + w2)
    return acc * half


@njit
def rise_integral(a, beta, u):
    """W(a, beta, u) = 2 int_0^{y(u)} e^{-y(2a+y)} f(a+y) dy, the column (in units of H times the
    density at the lower point) over a rise of u scale heights; u may be inf. W(a, beta, inf) is
    the Chapman function C(z, chi) with beta = z sin chi, a^2 = z - beta; W(0, z, inf) = C_h(z)."""
    u = min(u, U_CUT)
    if not u > 0.0:
        return 0.0
    y1 = _y_of_rise(a, min(u, U_SPLIT))
    acc = _panel(a, beta, 0.0, y1)
    if u > U_SPLIT:
        acc += _panel(a, beta, y1, _y_of_rise(a, u))
    return 2.0 * acc


# relative bound on `rise_integral`'s remainder for points at z >= Z (radius / scale height), with
# the rule's rounding (16 positive terms, exponents up to 40 off by 3 ulp: 160 ulp)
REMAINDER = ((3.0, 1e-11), (10.0, 1e-14))
RULE_ROUNDING = 160.0 * 2.0 ** -53


@njit
def relative_error(z_min):
    """A bound on the relative error of `rise_integral` (remainder and rounding) for columns whose
    points lie at z >= z_min (radius / scale height, >= 3 for every accepted layer)."""
    out = math.inf
    for z, bound in REMAINDER:
        if z_min >= z:
            out = bound
    return out + RULE_ROUNDING


_RHOS = (1.25, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 32.0, 64.0, 128.0, 1e3, 1e4, 1e6)


def panel_bound(a, beta, y0, y1, n=16):
    """A bound on |n-point Gauss-Legendre - exact| of int_{y0}^{y1} e^{-y(2a+y)} f(a+y) dy (module
    docstring): the least over the ellipses in _RHOS that keep f's branch points outside (their box
    does) of half-width (64/15) M rho^{-2n} / (rho^2 - 1), with |e^{-y(2a+y)}| = e^{a^2 - Re w^2}
    minimised over the ellipse in closed form (w = a + y), |beta + w^2| <= beta + max |w|^2 and
    |2 beta + w^2| >= the squared distance from ±i sqrt(2 beta) to the ellipse's box."""
    half, mid = 0.5 * (y1 - y0), 0.5 * (y0 + y1)
    if not half > 0.0:
        return 0.0
    s, p = math.sqrt(2.0 * beta), mid + a
    best = math.inf
    for rho in _RHOS:
        A, B = half * (rho + 1.0 / rho) / 2.0, half * (rho - 1.0 / rho) / 2.0
        dist = math.hypot(max(p - A, 0.0), max(s - B, 0.0))
        if not dist > 0.0:
            continue
        cs = (-1.0, 1.0, min(1.0, max(-1.0, -A * p / (A * A + B * B))))
        re_w2 = min((p + A * c) ** 2 - B * B * (1.0 - c * c) for c in cs)
        log_m = a * a - re_w2 + math.log(beta + (abs(p) + A) ** 2 + B * B) - math.log(dist)
        best = min(best, math.log(half * 64.0 / 15.0) + log_m - 2 * n * math.log(rho) - math.log(rho * rho - 1.0))
    return math.exp(best) if best < 700.0 else math.inf


def remainder_bound(a, beta, u):
    """A bound on |rise_integral(a, beta, u) - W(a, beta, u)| / W: both panels' `panel_bound` and the
    tail beyond U_CUT, over the rule's value less them (inf where that is not positive)."""
    value = rise_integral(a, beta, u)
    cut = min(u, U_CUT)
    y1 = _y_of_rise(a, min(cut, U_SPLIT))
    err = panel_bound(a, beta, 0.0, y1)
    if cut > U_SPLIT:
        err += panel_bound(a, beta, y1, _y_of_rise(a, cut))
    err *= 2.0
    if u > U_CUT:
        err += 2.0 * math.exp(-U_CUT) * (math.sqrt(beta) / (2.0 * math.sqrt(a * a + U_CUT)) + 0.5)
    return err / (value - err) if value > err else math.inf


@njit
def chapman(z, mu):
    """Chapman's grazing incidence integral C(z, chi) (eq. 42) for z > 0 and mu = cos chi in
    [-1, 1]. Below the horizon (mu < 0) it is eq. 48 without its subtraction: the column from the
    point back to the periapsis plus the periapsis' C_h, times e^{z - beta} (which may overflow
    to inf: the ray then crosses far denser layers than the point's)."""
    sin_chi = math.sqrt((1.0 - mu) * (1.0 + mu))
    beta = z * sin_chi
    a2 = z * mu * mu / (1.0 + sin_chi)  # z - beta
    if mu >= 0.0:
        return rise_integral(math.sqrt(a2), beta, math.inf)
    return math.exp(a2) * (rise_integral(0.0, beta, a2) + rise_integral(0.0, beta, math.inf))


@njit
def _altitude(h, r0, s0, b, t):
    """Altitude and radius at distance t along the ray, h + (r(t) - r0) without cancellation."""
    r = math.hypot(b, s0 + t)
    return h + t * ((2.0 * s0 + t) / (r + r0)), r


@njit
def _lift(s, r, b, H):
    """|s| / sqrt((r + b) H), the root of a point's height above the periapsis in scale heights
    ((r - b) / H, as s^2 = r^2 - b^2); 0 at the periapsis itself, where r + b may round to 0 (a ray
    through the centre of a planet far smaller than its distance)."""
    return abs(s) / math.sqrt((r + b) * H) if s != 0.0 else 0.0


@njit
def ground_distance(h, mu, radius):
    """Distance to the first hit of the planet (the sphere of the given radius) from a point at
    altitude h >= 0 looking at mu; inf if the ray misses it (or grazes it from h = 0 upward)."""
    if mu >= 0.0:
        return math.inf
    r0 = radius + h
    sin_chi = math.sqrt((1.0 - mu) * (1.0 + mu))
    b = r0 * sin_chi
    hp = h * sin_chi - radius * mu * mu / (1.0 + sin_chi)  # periapsis altitude b - R
    if hp >= 0.0:
        return math.inf
    # t = -r0 mu - sqrt(R^2 - b^2) = h (2R + h) / (-r0 mu + sqrt(R^2 - b^2))
    return h * (2.0 * radius + h) / (-r0 * mu + math.sqrt(-hp * (radius + b)))


@njit
def atmosphere_column(h, mu, t0, t1, radius, scale_height):
    """int_{t0}^{t1} exp(-h(t)/H) dt, the optical depth over sigma0 (eq. 40, 44), 0 <= t0 <= t1 <=
    inf. The planet is not an obstacle here: clip t1 at `ground_distance` for the ground's shadow
    (through the planet the value may be inf, never nan)."""
    if not t1 > t0:
        return 0.0
    H = scale_height
    r0 = radius + h
    sin_chi = math.sqrt((1.0 - mu) * (1.0 + mu))
    b = r0 * sin_chi
    beta = b / H
    s0 = r0 * mu  # signed distance of the origin past the periapsis
    sa = s0 + t0
    ha, ra = _altitude(h, r0, s0, b, t0)
    if t1 == math.inf:
        sb, hb, rb = math.inf, math.inf, math.inf
    else:
        sb = s0 + t1
        hb, rb = _altitude(h, r0, s0, b, t1)
    if sa >= 0.0:  # going away from the periapsis: rise from t0 to t1
        rise = math.inf if t1 == math.inf else (t1 - t0) * ((sa + sb) / (ra + rb)) / H
        col = math.exp(-ha / H) * rise_integral(_lift(sa, ra, b, H), beta, rise)
    elif sb <= 0.0:  # coming toward it: the same piece read from t1 back to t0
        rise = (t1 - t0) * (-(sa + sb) / (ra + rb)) / H
        col = math.exp(-hb / H) * rise_integral(_lift(sb, rb, b, H), beta, rise)
    else:  # through the periapsis: two pieces rising from it (eq. 48, split)
        hp = h * sin_chi - radius * mu * mu / (1.0 + sin_chi)
        rise_a = sa * sa / (ra + b) / H
        rise_b = math.inf if t1 == math.inf else sb * sb / (rb + b) / H
        col = math.exp(-hp / H) * (rise_integral(0.0, beta, rise_a) + rise_integral(0.0, beta, rise_b))
    return H * col


@njit
def atmosphere_optical_depth(sigma0, h, mu, t0, t1, radius, scale_height):
    """sigma0 times `atmosphere_column`: the optical depth between t0 and t1 (t1 may be inf)."""
    if sigma0 == 0.0:
        return 0.0
    return sigma0 * atmosphere_column(h, mu, t0, t1, radius, scale_height)


NEWTON_RTOL = 1e-14
NEWTON_MAX_ITER = 100


@njit
def atmosphere_distance(sigma0, h, mu, t0, tau, radius, scale_height, t_max):
    """The t in [t0, t_max] where the optical depth from t0 reaches tau (free-path sampling,
    eq. 24), or inf if it is not reached by t_max (t_max may be inf; pass `ground_distance` to stop
    at the planet). Safeguarded Newton as in the article (f' is the density, eq. 17): the iterate stays
    in a bracket [lo, hi] and falls back to bisection (or, while hi is inf, to doubling the step);
    it stops at |tau(t) - tau| <= 1e-14 tau, or returns the better end of a bracket of two
    neighbouring doubles (then the error is below one ulp of t times the extinction there)."""
    if not tau > 0.0:
        return t0
    if not sigma0 > 0.0:
        return math.inf
    H = scale_height
    target = tau / sigma0
    total = atmosphere_column(h, mu, t0, t_max, radius, scale_height)
    if total < target:
        return math.inf
    r0 = radius + h
    b = r0 * math.sqrt((1.0 - mu) * (1.0 + mu))
    s0 = r0 * mu
    lo, hi = t0, t_max
    f_lo, f_hi = -target, total - target
    ha, _ = _altitude(h, r0, s0, b, t0)
    dens = math.exp(-ha / H)
    t = t0 + (target / dens if dens > 0.0 else H)
    if not t < hi:
        t = 0.5 * (lo + hi)
    for _ in range(NEWTON_MAX_ITER):
        f = atmosphere_column(h, mu, t0, t, radius, scale_height) - target
        if abs(f) <= NEWTON_RTOL * target:
            return t
        if f < 0.0:
            lo, f_lo = t, f
        else:
            hi, f_hi = t, f
        mid = 0.5 * (lo + hi)
        if hi < math.inf and not lo < mid < hi:  # lo, hi are neighbouring doubles
            return lo if -f_lo <= f_hi else hi
        ht, _ = _altitude(h, r0, s0, b, t)
        dens = math.exp(-ht / H)
        t_new = t - f / dens if dens > 0.0 else math.inf
        if not lo < t_new < hi:
            t_new = mid if hi < math.inf else lo + 2.0 * (lo - t0 + H)
        t = t_new
    return t


# numpy-broadcasting wrappers (tests, Python callers); kernels should call the scalar functions
chapman_np = np.vectorize(chapman, otypes=[float])
ground_distance_np = np.vectorize(ground_distance, otypes=[float])
atmosphere_column_np = np.vectorize(atmosphere_column, otypes=[float])
atmosphere_optical_depth_np = np.vectorize(atmosphere_optical_depth, otypes=[float])
atmosphere_distance_np = np.vectorize(atmosphere_distance, otypes=[float])
