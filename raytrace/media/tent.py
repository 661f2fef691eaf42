"""A tent layer of a planet's atmosphere (Bruneton's ozone): density max(0, 1 - |a - P| / W) of
the altitude a, peak P, half-width W; its column along a ray in closed form (docs/optical_depth.md
§3).

A ray is given, as in atmosphere.py, by the altitude h >= 0 and zenith cosine mu of its origin on
the planet of radius R; with r0 = R + h and s0 = r0 mu, the point at distance t lies at s = s0 + t
from the ray's tangent point (its lowest), at radius r(s) = sqrt(b^2 + s^2), b^2 = r0^2 (1 - mu^2).
Its altitude is written without the cancellation of r(t) - R:

    a(t) = (h (2R + h) + t (2 s0 + t)) / (r(t) + R).

The density is linear in r on each piece of the ray between its crossings of the spheres at
P - W, P, P + W and its tangent point, where r is monotonic. On such a piece from (s1, r1) to
(s2, r2), of length L, the column is ((a1 - (P - W)) L + J) / W (below the peak) or
((P + W - a1) L - J) / W (above it), J = ∫ (r - r1) ds. With q = s + r (r = (q + b^2/q)/2) and
lambda = ln(q2 / q1), J is exactly

    J = (L e - b^2 (sinh(lambda) - lambda)) / 2,      e = r2 - r1 = L (s1 + s2) / (r1 + r2),

whose two terms have the same sign on inward pieces and differ by a factor >= 3 on outward
ones; lambda = log1p((L + e) / (s1 + r1)) outward, log1p((L - e) / (r2 - s2)) inward, and
sinh(lambda) - lambda by its series below 1: no difference of large numbers anywhere.
"""
import math

from ..jit import njit

@njit
def altitude(h, mu, t, radius):
    """The altitude at distance t along the ray, without cancellation (module docstring)."""
    r0 = radius + h
    u = t * (2.0 * r0 * mu + t)
    r = math.sqrt(max(r0 * r0 + u, 0.0))
    return (h * (2.0 * radius + h) + u) / (r + radius)


@njit
def sphere_crossings(h, mu, alt, radius):
    """(t_-, t_+, s_+): the distances where the ray (all t, also negative) crosses the sphere of
    altitude alt, each from products (no cancellation of -s0 -+ s_+), and s_+ = sqrt((R + alt)^2 - b^2),
    their distance from the tangent point; (nan, nan, nan) if it does not cross it."""
    r0 = radius + h
    s0 = r0 * mu
    near = (alt - h) * (2.0 * radius + alt + h)  # (s_+ - s0)(s_+ + s0)
    disc = near + s0 * s0
    if not disc > 0.0:
        return math.nan, math.nan, math.nan
    half = math.sqrt(disc)
    if s0 > 0.0:
        return -(s0 + half), near / (half + s0), half
    return -near / (half - s0), half - s0, half


@njit
def _sinh_minus(x):
    """sinh(x) - x for x >= 0 to full relative precision (its series below 1)."""
    if x >= 1.0:
        return math.sinh(x) - x
    x2 = x * x
    term = x * x2 / 6.0
    total = term
    k = 3
    while term > 1e-17 * total:
        term *= x2 / ((k + 1) * (k + 2))
        total += term
        k += 2
    return total


@njit
def _piece(s1, a1, s2, a2, length, b2, radius, peak, half_width, rising):
    """The unit column over one piece (module docstring): altitudes a1 -> a2, s1 -> s2 of one sign."""
    r1, r2 = radius + a1, radius + a2
    e = length * (s1 + s2) / (r1 + r2)
    if e >= 0.0:  # outward
        lam = math.log1p((length + e) / (s1 + r1))
    else:
        lam = math.log1p((length - e) / (r2 - s2))
    j = 0.5 * (length * e - b2 * _sinh_minus(lam))
    if rising:
        return max(((a1 - (peak - half_width)) * length + j) / half_width, 0.0)
    return max(((peak + half_width - a1) * length - j) / half_width, 0.0)


@njit
def _crossing(h, mu, j, radius, peak, half_width):
    """(t, s, altitude) of the ray's j-th kink in ascending t (j = 0 ... 6): its crossings of the
    spheres at P + W, P, P - W going down, its tangent point (j = 3), the same spheres going up;
    t = nan where the ray misses that sphere."""
    if j == 3:
        s0 = (radius + h) * mu
        return -s0, 0.0, altitude(h, mu, -s0, radius)
    alt = peak + (1 - j if j < 3 else j - 5) * half_width
    down, up, half = sphere_crossings(h, mu, alt, radius)
    return (down, -half, alt) if j < 3 else (up, half, alt)


@njit
def tent_column(h, mu, t0, t1, radius, peak, half_width):
    """The unit-density column over [t0, t1] (finite, t0 <= t1) of the tent along the ray: the sum
    of `_piece` over the parts between its kinks inside the tent."""
    if not t1 > t0:
        return 0.0
    r0 = radius + h
    s0 = r0 * mu
    b2 = r0 * r0 * (1.0 - mu) * (1.0 + mu)
    ta, sa, aa = t0, s0 + t0, altitude(h, mu, t0, radius)
    total = 0.0
    for j in range(8):
        if j < 7:
            tb, sb, ab = _crossing(h, mu, j, radius, peak, half_width)
            if not t0 < tb < t1:  # also nan
                continue
        else:
            tb, sb, ab = t1, s0 + t1, altitude(h, mu, t1, radius)
        mid = altitude(h, mu, 0.5 * (ta + tb), radius)
        if tb > ta and abs(mid - peak) < half_width:
            total += _piece(sa, aa, sb, ab, tb - ta, b2, radius, peak, half_width, mid < peak)
        ta, sa, aa = tb, sb, ab
    return total


@njit
def tent_density(alt, peak, half_width):
    """max(0, 1 - |alt - peak| / half_width)."""
    return max(0.0, 1.0 - abs(alt - peak) / half_width)


@njit
def tent_breaks(h, mu, radius, peak, half_width, out):
    """The distances (any sign) where the ray crosses the tent's three spheres, into out (6); their count."""
    n = 0
    for k in range(3):
        lo, hi, _ = sphere_crossings(h, mu, peak + (k - 1) * half_width, radius)
        if lo == lo:
            out[n], out[n + 1] = lo, hi
            n += 2
    return n

