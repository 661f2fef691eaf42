"""The refracted paths to an inside point of a refractive exact sphere (media/sphere_refraction.py
`paths`), against an independent root finder built from the geometry alone.

The reference: in the plane of the light's axis and the point X = (z, y), the refraction point
P(theta) = (cos theta, sin theta) of the unit sphere makes the optical path F(theta) = |P - L| +
eta |X - P| (for the sun, -P_z + eta |X - P|) stationary (Fermat); the roots of F' are bracketed on
20001 nodes of the lit arc, the arc's dips (|F'| least without a sign change) minimised by scipy's
bounded minimizer, and each root solved by mpmath's bisection-safe solver at 30 digits. The bound
that `paths` halves its cells on (`angular_bounds`: |phi'|, |phi''| of the refracted direction's
angle, and so |h''|) is checked against mpmath's derivatives of the refracted direction computed by
Snell's law in the same plane.
"""
import math

import mpmath
import numpy as np
import pytest
from scipy import optimize

from raytrace.media.sphere_refraction import angular_bounds, frame, paths, record, third_bound

SPHERE = np.array([0.0, 0.0, 0.0, 1.0])


def rec(eta, d):
    """The kernel's record of a unit sphere at the origin lit along z by a light at distance d (inf: the sun)."""
    geo = np.zeros(18)
    geo[6:9] = [0.0, 0.0, 1.0] if d == math.inf else [0.0, 0.0, d]
    geo[12:14], geo[17] = [-2.0, -1.0], 0
    distant = d == math.inf
    return record(SPHERE, geo, distant, eta, 1.0, 0.5, 0, 0.0, 0.0, frame(SPHERE, geo[6:9].copy(), distant, eta))


def arc(eta, d):
    """The lit arc's half-width from the geometry: incidence cosine 0 (or the critical angle for eta < 1)."""
    def cos_i(th):
        if d == math.inf:
            return math.cos(th)
        return (d * math.cos(th) - 1.0) / math.hypot(math.cos(th) - d, math.sin(th))
    c_min = math.sqrt(1.0 - eta * eta) if eta < 1.0 else 0.0
    hi = 0.5 * math.pi if d == math.inf else math.acos(1.0 / d)
    return hi if c_min == 0.0 else optimize.brentq(lambda t: cos_i(t) - c_min, 0.0, hi, xtol=1e-16)


def slope(th, X, eta, d):
    """F'(theta), numpy (th an array) or mpmath (th an mpf)."""
    lib = mpmath if isinstance(th, mpmath.mpf) else np
    c, s = lib.cos(th), lib.sin(th)
    outside = s if d == math.inf else (d * s) / lib.sqrt((c - d) ** 2 + s * s)
    return outside + eta * ((X[0] * s) - X[1] * c) / lib.sqrt((c - X[0]) ** 2 + (s - X[1]) ** 2)


def reference(X, eta, d):
    """Fermat's stationary points on the lit arc (module docstring)."""
    a = arc(eta, d) * (1.0 - 1e-12)
    ths = np.linspace(-a, a, 20001)
    fs = slope(ths, X, eta, d)
    mpmath.mp.dps = 30

    def solve(lo, hi):
        return float(mpmath.findroot(lambda t: slope(t, X, eta, d), (mpmath.mpf(lo), mpmath.mpf(hi)),
                                     solver="anderson"))

    found = [solve(ths[j], ths[j + 1]) for j in np.nonzero(fs[:-1] * fs[1:] < 0.0)[0]]
    for j in range(1, len(ths) - 1):
        if fs[j - 1] * fs[j] > 0 and fs[j] * fs[j + 1] > 0 and abs(fs[j]) < min(abs(fs[j - 1]), abs(fs[j + 1])):
            sign = math.copysign(1.0, fs[j])
            best = optimize.minimize_scalar(lambda t: sign * slope(t, X, eta, d), bounds=(ths[j - 1], ths[j + 1]),
                                            method="bounded", options={"xatol": 1e-15})
            if best.fun < 0.0:
                found += [solve(ths[j - 1], best.x), solve(best.x, ths[j + 1])]
    return sorted(found)


def ray(th, eta, d):
    """(P, t) of the ray refracted at P(theta), mpmath or float, from Snell's law in the plane."""
    lib = mpmath if isinstance(th, mpmath.mpf) else np
    P = [lib.cos(th), lib.sin(th)]
    if d == math.inf:
        v = [-1.0, 0.0]
    else:
        o = lib.sqrt((P[0] - d) ** 2 + P[1] ** 2)
        v = [(P[0] - d) / o, P[1] / o]
    ci = -(v[0] * P[0] + v[1] * P[1])
    ct = lib.sqrt(1 - (1 - ci * ci) / eta**2)
    return P, [v[k] / eta + (ci / eta - ct) * P[k] for k in range(2)]


def angle(th, eta, d):
    """The refracted direction's angle phi, continuous over the lit arc (t points back along the axis; mpmath)."""
    t = ray(th, eta, d)[1]
    return mpmath.atan2(-t[1], -t[0]) + mpmath.pi


def caustic_point(th, eta, d):
    """The envelope of the refracted rays at theta: P + s t where d(P + s t)/dtheta is along t (mpmath)."""
    mpmath.mp.dps = 30
    th = mpmath.mpf(th)
    P, t = ray(th, eta, d)
    dP = [mpmath.diff(lambda u: ray(u, eta, d)[0][k], th) for k in range(2)]
    dt = [mpmath.diff(lambda u: ray(u, eta, d)[1][k], th) for k in range(2)]
    s = -(dP[0] * t[1] - dP[1] * t[0]) / (dt[0] * t[1] - dt[1] * t[0])
    return np.array([float(P[0] + s * t[0]), float(P[1] + s * t[1])]), float(s)


def points(rng, eta, d, n):
    """Random inside points: uniform in the half disc, near the caustic (both sides), near its cusp on
    the axis and near the marginal ray (both sides)."""
    out = []
    while len(out) < n:
        z, y = rng.uniform(-1.0, 1.0), rng.uniform(0.0, 1.0)
        if z * z + y * y < 0.999:
            out.append((z, y))
    a = arc(eta, d)
    for th in rng.uniform(0.05, 0.999, n) * a:
        C, s = caustic_point(th, eta, d)
        P, t = ray(th, eta, d)
        normal = np.array([-t[1], t[0]])
        for step in (1e-3, 1e-5, 1e-6):
            for sign in (-1.0, 1.0):
                X = C + sign * step * normal
                if X @ X < 0.999 and s > 0.0:
                    out.append(tuple(X))
    C, _ = caustic_point(1e-4, eta, d)  # the cusp, near the axis
    for dz in (-1e-3, 1e-4, 1e-3):
        for y in (1e-6, 1e-4, 1e-2):
            if (C[0] + dz) ** 2 + y * y < 0.999:
                out.append((C[0] + dz, y))
    P, t = ray(a * (1.0 - 1e-13), eta, d)
    for s in rng.uniform(0.1, 0.9, 4) * 2.0 * abs(P[0] * t[0] + P[1] * t[1]):
        for off in (-1e-4, -1e-6, 1e-6, 1e-4):
            X = np.array(P) + s * np.array(t) + off * np.array([-t[1], t[0]])
            if X @ X < 0.999 and X[1] > 0.0:
                out.append(tuple(X))
    return out


CASES = [(1.33, 2.5), (1.5, math.inf), (1.33, math.inf), (2.2, math.inf), (2.6, 3.0), (1.5, 1.2), (1.05, 6.0)]


@pytest.mark.parametrize("eta, d", CASES)
def test_paths_are_every_root(eta, d):
    """Every path the reference finds, and no other, to 1e-9 in theta and within its spread (the bound
    on its distance from the exact root), on random inside points, points 1e-3 to 1e-6 from the
    caustic, near its cusp and 1e-4 to 1e-6 from the marginal ray; every scan proven."""
    rng = np.random.default_rng(int(eta * 100) + (0 if d == math.inf else int(d * 10)))
    r = rec(eta, d)
    pts = points(rng, eta, d, 16)
    spreads = []
    for z, y in pts:
        found, spread = np.empty(8), np.empty(8)
        m, proven = paths(r, z, y, 0.0, found, spread)
        ref = reference((z, y), eta, d)
        assert proven, (z, y)
        assert m == len(ref) and np.allclose(found[:m], ref, rtol=0.0, atol=1e-9), (z, y, found[:m], ref)
        assert np.all(np.abs(found[:m] - ref) <= spread[:m]), (z, y, found[:m] - ref, spread[:m])
        spreads += list(spread[:m])
    assert np.median(spreads) < 1e-10, np.median(spreads)  # about the root, not the cell's weakest slope
    print(eta, d, len(pts), "points; spreads' median and largest", np.median(spreads), max(spreads))


@pytest.mark.parametrize("eta, d", CASES + [(0.75, 2.0)])
def test_angular_bounds_hold(eta, d):
    """|phi'|, |phi''| (mpmath's derivatives of the refracted direction's angle) and |h''| of random
    points within `angular_bounds` over random cells of the lit arc."""
    mpmath.mp.dps = 30
    rng = np.random.default_rng(7)
    a = arc(eta, d)
    r = rec(eta, d)
    worst = 0.0
    for _ in range(24):
        lo, hi = np.sort(rng.uniform(-a, a, 2))
        p1, p2, _, _ = angular_bounds(lo, hi, 1.0, d, eta)
        X = (rng.uniform(-0.7, 0.7), rng.uniform(0.0, 0.7))
        reach = math.hypot(*X) + 1.0
        k = (p2 + p1 * p1) * reach + 2.0 * p1 + 1.0
        for th in np.linspace(lo, hi, 3):
            th = mpmath.mpf(th)

            def phi(u):
                t = ray(u, eta, d)[1]
                return mpmath.atan2(t[1], t[0])

            def h(u):
                P, t = ray(u, eta, d)
                return t[0] * (X[1] - P[1]) - t[1] * (X[0] - P[0])

            d1, d2 = abs(mpmath.diff(phi, th)), abs(mpmath.diff(phi, th, 2))
            h2 = abs(mpmath.diff(h, th, 2))
            assert d1 <= p1 and d2 <= p2 and h2 <= k, (lo, hi, th, d1, p1, d2, p2, h2, k)
            worst = max(worst, float(d2 / p2), float(h2 / k))
    assert r.theta_a == pytest.approx(a, rel=1e-12)
    assert worst > 0.05, worst  # not vacuous


@pytest.mark.parametrize("eta, d", CASES + [(0.75, 2.0)])
def test_third_derivative_in_closed_form(eta, d):
    """The closed forms of the module docstring that the proven scan of the caustic's crossings
    bounds (phi''' through g'', g''' of the refraction angle in the incidence angle and alpha'', alpha'''
    of the arriving direction's angle) against mpmath's derivatives of the refracted direction's angle."""
    mpmath.mp.dps = 40
    rng = np.random.default_rng(3)
    a = arc(eta, d)

    def phi(u):
        return angle(u, eta, d)

    for th in rng.uniform(-0.95, 0.95, 6) * a:
        th = mpmath.mpf(th)
        if d == math.inf:
            alpha, a1, a2, a3 = mpmath.pi, 0, 0, 0
        else:
            o2 = 1 + d * d - 2 * d * mpmath.cos(th)
            alpha = mpmath.atan2(mpmath.sin(th), mpmath.cos(th) - d)
            a1 = (1 - d * mpmath.cos(th)) / o2
            a2 = d * mpmath.sin(th) * (d * d - 1) / o2**2
            a3 = d * (d * d - 1) / o2**2 * (mpmath.cos(th) - 4 * d * mpmath.sin(th) ** 2 / o2)
        s, c = mpmath.sin(alpha - th - mpmath.pi), mpmath.cos(alpha - th - mpmath.pi)
        ct = mpmath.sqrt(1 - s * s / eta**2)
        g1, g2 = c / (eta * ct), s * (1 - eta**2) / (eta**3 * ct**3)
        g3 = (1 - eta**2) * c * (eta**2 * ct**2 + 3 * s * s) / (eta**5 * ct**5)
        i1 = a1 - 1
        closed = (1 + g1 * i1, g2 * i1**2 + g1 * a2, g3 * i1**3 + 3 * g2 * i1 * a2 + g1 * a3)
        for k in range(3):
            want = mpmath.diff(phi, th, k + 1)
            assert abs(closed[k] - want) <= 1e-12 * max(abs(want), 1), (k + 1, th, closed[k], want)


@pytest.mark.parametrize("eta, d", CASES)
def test_third_derivative_bound_holds(eta, d):
    """|phi'''| (mpmath's) over random cells of the lit arc within the bound of the module docstring,
    taken as `angular_bounds` takes its bounds at the cell's extreme ends: G3 (1 + a1)^3 + 3 G2 (1 + a1)
    a2 + G1 a3 with G1 = 1 / (eta cos_t), G2 = |eta^2 - 1| / (eta^3 cos_t^3), G3 = |eta^2 - 1| (eta^2 + 2)
    / (eta^5 cos_t^5) at the least cos_t, and a1, a2, a3 the bounds on |alpha'|, |alpha''|, |alpha'''|
    (the least o^2 at the smaller |theta|, the largest sin(theta) at the larger); not vacuous."""
    mpmath.mp.dps = 30
    rng = np.random.default_rng(11)
    a = arc(eta, d)

    def phi(u):
        return angle(u, eta, d)

    worst = 0.0
    for _ in range(16):
        lo, hi = np.sort(rng.uniform(-a, a, 2))
        m_lo = 0.0 if lo <= 0.0 <= hi else min(abs(lo), abs(hi))
        m_hi = max(abs(lo), abs(hi))
        P, t = ray(m_hi, eta, d)
        ct = -(t[0] * P[0] + t[1] * P[1])  # the least refraction cosine (the incidence grows with |theta|)
        a1 = a2 = a3 = 0.0
        if d != math.inf:
            o2 = 1.0 + d * d - 2.0 * d * math.cos(m_lo)
            a1 = (d * math.cos(m_lo) - 1.0) / o2
            a2 = d * math.sin(m_hi) * (d * d - 1.0) / o2**2
            a3 = d * (d * d - 1.0) / o2**2 * (1.0 + 4.0 * d * math.sin(m_hi) ** 2 / o2)
        g1, g2 = 1.0 / (eta * ct), abs(eta**2 - 1.0) / (eta**3 * ct**3)
        g3 = abs(eta**2 - 1.0) * (eta**2 + 2.0) / (eta**5 * ct**5)
        p3 = g3 * (1.0 + a1) ** 3 + 3.0 * g2 * (1.0 + a1) * a2 + g1 * a3
        for th in np.linspace(lo, hi, 3):
            d3 = float(abs(mpmath.diff(phi, mpmath.mpf(th), 3)))
            assert d3 <= p3, (lo, hi, th, d3, p3)
            worst = max(worst, d3 / p3)
    assert worst > 0.05, worst


@pytest.mark.parametrize("eta, d", CASES)
def test_kernels_third_bound_holds(eta, d):
    """`third_bound`'s bounds on |phi''| and |phi'''| (the caustic scan's, sphere_refraction.py
    `caustic_crossings`) over random cells of the lit arc, also of a sphere of radius 1.7 with the
    light at the same d in radii: mpmath's derivatives within them, not vacuous."""
    mpmath.mp.dps = 30
    rng = np.random.default_rng(13)
    a = arc(eta, d)

    def phi(u):
        return angle(u, eta, d)

    worst = [0.0, 0.0]
    for _ in range(16):
        lo, hi = np.sort(rng.uniform(-a, a, 2))
        q2, p3, _ = third_bound(lo, hi, 1.0, d, eta)
        assert third_bound(lo, hi, 1.7, 1.7 * d, eta)[:2] == pytest.approx((q2, p3), rel=1e-12)
        for th in np.linspace(lo, hi, 3):
            d2, d3 = (float(abs(mpmath.diff(phi, mpmath.mpf(th), k))) for k in (2, 3))
            assert d2 <= q2 and d3 <= p3, (lo, hi, th, d2, q2, d3, p3)
            worst = [max(worst[0], d2 / q2), max(worst[1], d3 / p3)]
    assert min(worst) > 0.05, worst
