"""Where a segment inside a refractive exact sphere crosses the band edges of a spot not aimed at its
centre (media/sphere_refraction.py `spot_edges` through `edge_crossings`, the proven halving scan over
the edge rays), against a reference built from the geometry alone.

The reference: along the segment, in the plane of the light's axis and each point X, the spot's cone
meets the plane in at most two directions out of the light (its cosine to the spot's axis a sinusoid
of the direction's angle there); the ray along each meets the sphere at P and refracts (Snell's law)
along t, and h = t x (X - P) in the plane is 0 where X lies on it. h's roots in x are bracketed on
20001 nodes of the segment (and 20001 more within 1e-3 of a tangent line's touching point), its dips
(least |h| without a sign change) minimised by scipy's bounded minimizer, and each root solved by
mpmath's solver at 30 digits; those ahead of P count. Configurations: lamps 1.3 to 5 radii away, spots
aimed 0.2 to 1.5 radii off the centre with cones of 3 to 35 degrees (lighting part of the sphere, its
rim included, or all of it), eta 1.33, 1.5, 2.2 and 0.75; random lines through the sphere and lines
tangent to a band edge's surface moved off it by 1e-3, 1e-6 and 1e-9 along its normal (two crossings
close together, or none). The bound `edge_crossings` halves its cells on (`edge_bound`) is checked
against mpmath's second derivative of the edge function, and its derivative test's G' (`edge_slope`)
against mpmath's first derivative, within its rounding bound.
"""
import math

import mpmath
import numpy as np
import pytest
from scipy import optimize

from raytrace.media.sphere_refraction import UNRESOLVED, edge_bound, edge_cone, edge_gap, edge_ray, edge_slope, \
    frame, record, spot_edges

ETAS = (1.33, 1.5, 2.2, 0.75)


def gap(x, o, w, L, a, ce, eta, sgn, lib=np):
    """(h, s) of the edge ray of sign sgn in the plane of X = o + x w (unit sphere at the origin): s the
    distance from P along t to X's foot; nan where the plane holds no such ray entering the sphere."""
    mp = lib is mpmath
    if mp:
        o, w, L, a = ([mpmath.mpf(float(c)) for c in v] for v in (o, w, L, a))
        ce, eta = mpmath.mpf(ce), mpmath.mpf(eta)
    else:
        x = np.asarray(x, dtype=float)
    X = [o[k] + x * w[k] for k in range(3)]
    d = lib.sqrt(L[0] ** 2 + L[1] ** 2 + L[2] ** 2)
    ez = [L[k] / d for k in range(3)]
    zx = X[0] * ez[0] + X[1] * ez[1] + X[2] * ez[2]
    yx = lib.sqrt(sum((X[k] - zx * ez[k]) ** 2 for k in range(3)))
    ay = sum(a[k] * (X[k] - zx * ez[k]) for k in range(3)) / yx
    az = a[0] * ez[0] + a[1] * ez[1] + a[2] * ez[2]
    amp = lib.sqrt(az * az + ay * ay)
    if mp and not amp > abs(ce):
        return mpmath.nan, mpmath.nan
    ratio = ce / amp if mp else np.clip(ce / amp, -2.0, 2.0)
    acos = mpmath.acos if mp else (lambda v: np.arccos(np.where(abs(v) <= 1.0, v, np.nan)))
    beta = (mpmath.atan2 if mp else np.arctan2)(ay, -az) + sgn * acos(ratio)
    cb, sb = lib.cos(beta), lib.sin(beta)
    disc = 1.0 - d * d * sb * sb
    if mp and not (cb > 0 and disc >= 0):
        return mpmath.nan, mpmath.nan
    rho = d * cb - lib.sqrt(disc if mp else np.where(disc >= 0.0, disc, np.nan))
    pz, py = d - rho * cb, rho * sb
    ci = pz * cb - py * sb
    ct2 = 1 - (1 - ci * ci) / (eta * eta)
    if mp and not ct2 > 0:
        return mpmath.nan, mpmath.nan
    ct = lib.sqrt(ct2 if mp else np.where((ct2 > 0.0) & (cb > 0.0), ct2, np.nan))
    f = ci / eta - ct
    tz, ty = -cb / eta + f * pz, sb / eta + f * py
    return tz * (yx - py) - ty * (zx - pz), tz * (zx - pz) + ty * (yx - py)


def reference(o, w, end, L, a, ces, eta, dense=()):
    """The x in (0, end) where a refracted path crosses one of the band edges (module docstring)."""
    xs = np.linspace(0.0, end, 20001)
    for c in dense:
        xs = np.concatenate([xs, np.clip(c + np.linspace(-1e-3, 1e-3, 20001), 0.0, end)])
    xs = np.unique(xs)
    mpmath.mp.dps = 30
    out = []
    with np.errstate(invalid="ignore", divide="ignore"):
        for ce in ces:
            for sgn in (1.0, -1.0):
                hs = gap(xs, o, w, L, a, ce, eta, sgn)[0]

                def solve(lo, hi):
                    return float(mpmath.findroot(lambda x: gap(x, o, w, L, a, ce, eta, sgn, mpmath)[0],
                                                 (mpmath.mpf(lo), mpmath.mpf(hi)), solver="anderson"))
                found = [solve(xs[j], xs[j + 1]) for j in np.nonzero(hs[:-1] * hs[1:] < 0.0)[0]]
                for j in np.nonzero(np.isnan(hs[:-1]) != np.isnan(hs[1:]))[0]:  # where the plane's edge ray
                    # stops entering (h's square root there): a root between the node and the last valid point
                    node, good, bad = (j, xs[j], xs[j + 1]) if hs[j] == hs[j] else (j + 1, xs[j + 1], xs[j])
                    for _ in range(60):
                        mid = 0.5 * (good + bad)
                        if mpmath.isnan(gap(mpmath.mpf(mid), o, w, L, a, ce, eta, sgn, mpmath)[0]):
                            bad = mid
                        else:
                            good = mid
                    if gap(mpmath.mpf(good), o, w, L, a, ce, eta, sgn, mpmath)[0] * hs[node] < 0.0:
                        found.append(solve(*sorted((good, xs[node]))))
                for j in np.nonzero((hs[:-2] * hs[1:-1] > 0) & (hs[1:-1] * hs[2:] > 0) &
                                    (abs(hs[1:-1]) < np.minimum(abs(hs[:-2]), abs(hs[2:]))))[0] + 1:
                    sign = math.copysign(1.0, hs[j])
                    best = optimize.minimize_scalar(lambda x: sign * gap(np.array([x]), o, w, L, a, ce, eta, sgn)[0][0],
                                                    bounds=(xs[j - 1], xs[j + 1]), method="bounded",
                                                    options={"xatol": 1e-16})
                    if best.fun < 0.0:
                        found += [solve(xs[j - 1], best.x), solve(best.x, xs[j + 1])]
                out += [x for x in found if 0.0 < x < end and gap(mpmath.mpf(x), o, w, L, a, ce, eta, sgn,
                                                                   mpmath)[1] >= 0]
    return sorted(out)


def rec(o, w, eta, L, axis, ce, cs, centre=np.zeros(3), radius=1.0):
    """The kernel's record of the segment o + x w in a sphere (unit-sphere coordinates, scaled and moved
    with it) under a spot at L along axis with the band (ce, cs)."""
    sphere = np.array([*centre, radius])
    geo = np.zeros(18)
    geo[:3], geo[3:6], geo[6:9], geo[9:12] = centre + radius * np.asarray(o), w, centre + radius * L, axis
    geo[12:14], geo[17] = [ce, cs], 0
    return record(sphere, geo, False, eta, 1.0, 0.5, 0, 0.0, 0.0, frame(sphere, geo[6:9].copy(), False, eta))


def kernel(o, w, end, eta, L, axis, ce, cs, centre=np.zeros(3), radius=1.0):
    """(the x of `spot_edges` in unit-sphere units, proven)."""
    r = rec(o, w, eta, L, axis, ce, cs, centre, radius)
    spot_edges(r, end * radius)
    n = int(r.edges[0])
    return list(r.edges[1:n + 1] / radius), r.track[UNRESOLVED] == 0.0


def spots(rng, n):
    """(L, axis, ce, cs): lamps 1.3 to 5 radii away, aimed 0.2 to 1.5 radii off the centre, cones of 3
    to 35 degrees (the inner edge at 0.7 of the outer angle)."""
    out = []
    for _ in range(n):
        L = rng.normal(size=3)
        L *= rng.uniform(1.3, 5.0) / np.linalg.norm(L)
        off = rng.normal(size=3)
        off *= rng.uniform(0.2, 1.5) / np.linalg.norm(off)
        axis = (off - L) / np.linalg.norm(off - L)
        ang = math.radians(rng.uniform(3.0, 35.0))
        out.append((L, axis, math.cos(ang), math.cos(0.7 * ang)))
    return out


def chord(o, w):
    """The distance from o (inside the unit sphere) along w to its boundary."""
    b = o @ w
    return -b + math.sqrt(b * b - o @ o + 1.0)


def edge_point(L, axis, ce, eta, psi, s0):
    """(X, t, N): a point of the edge's refracted surface (the ray along the cone's direction at azimuth
    psi about the axis, s0 of its chord inside), the ray's direction and the surface's unit normal (its
    derivative in psi by the complex step); None where that ray misses or does not enter."""
    b1 = np.cross(axis, [0.3, 0.5, 0.8])
    b1 /= np.linalg.norm(b1)
    b2 = np.cross(axis, b1)

    def point(p):
        u = ce * axis + math.sqrt(1.0 - ce * ce) * (np.cos(p) * b1 + np.sin(p) * b2)
        bq = L @ u
        disc = bq * bq - L @ L + 1.0
        P = L + (-bq - np.sqrt(disc)) * u
        ci = -(P @ u)
        ct = np.sqrt(1.0 - (1.0 - ci * ci) / eta ** 2)
        t = u / eta + (ci / eta - ct) * P
        return P + s0 * (-2.0 * (P @ t)) * t, t
    u = ce * axis + math.sqrt(1.0 - ce * ce) * (math.cos(psi) * b1 + math.sin(psi) * b2)
    bq = L @ u
    if not (bq < 0.0 and bq * bq - L @ L + 1.0 > 0.0):
        return None
    P = L + (-bq - math.sqrt(bq * bq - L @ L + 1.0)) * u
    if (P @ u) ** 2 <= 1.0 - eta * eta:
        return None
    X, t = point(psi)
    dX = point(psi + 1e-30j)[0].imag / 1e-30
    N = np.cross(t, dX)
    return X, t, N / np.linalg.norm(N)


def lines(rng, L, axis, ce, eta, n):
    """(o, w, end, x0, off): n random lines through the sphere (x0 None); lines tangent to the band
    edge's surface at n random points of it (where its rays enter) moved off by off along its normal
    (either side), x0 where they touch it."""
    out = []
    for _ in range(n):
        o = rng.normal(size=3)
        o *= rng.uniform(0.0, 0.95) / np.linalg.norm(o)
        w = rng.normal(size=3)
        w /= np.linalg.norm(w)
        out.append((o, w, chord(o, w), None, None))
    tries = touching = 0
    while touching < n and tries < 200:
        tries += 1
        got = edge_point(L, axis, ce, eta, rng.uniform(0.0, 2.0 * math.pi), rng.uniform(0.2, 0.8))
        if got is None or got[0] @ got[0] > 0.9:
            continue
        X, t, N = got
        side = np.cross(N, t)
        beta = rng.choice([-1.0, 1.0]) * rng.uniform(0.4, 1.3)
        w = math.cos(beta) * t + math.sin(beta) * side / np.linalg.norm(side)
        touching += 1
        for off in (1e-3, 1e-6, 1e-9):
            for sign in (-1.0, 1.0):
                p = X + sign * off * N
                back = chord(p, -w)
                out.append((p - back * w, w, back + chord(p, w), back, sign * off))
    return out


def random_cones(rng, eta, n):
    """The edge cones (`edge_cone`, mode 0 left out) of n random spots and one just off the axis, each
    from a random segment in the ball."""
    for L, axis, ce, cs in spots(rng, n) + [(np.array([0.0, 0.0, 4.0]), np.array([0.05, 0.0, -1.0]) /
                                             math.hypot(0.05, 1.0), math.cos(0.1), 0.999)]:
        o = rng.normal(size=3)
        o *= rng.uniform(0.0, 0.95) / np.linalg.norm(o)
        w = rng.normal(size=3)
        k = edge_cone(rec(o, w / np.linalg.norm(w), eta, L, axis, ce, cs), ce)
        if k.mode != 0:
            yield k


@pytest.mark.parametrize("eta", ETAS)
def test_every_crossing_is_found(eta):
    """On random lines and lines 1e-3 to 1e-9 from tangent to a band edge's surface: the scan proven on
    every one (1e-9 off, the derivative test decides the cells beside the nearly double root, where G is
    within its rounding of 0) and the crossings the reference's to 1e-9, none missed; a sphere of
    radius 1.7 off the origin gives the same crossings."""
    rng = np.random.default_rng(int(eta * 100))
    total = near = lines_in = 0
    for L, axis, ce, cs in spots(rng, 6):
        for o, w, end, x0, off in lines(rng, L, axis, ce, eta, 4):
            lines_in += 1
            want = reference(o, w, end, L, axis, (ce, cs), eta, () if x0 is None else (x0,))
            got, proven = kernel(o, w, end, eta, L, axis, ce, cs)
            moved, proven_moved = kernel(o, w, end, eta, L, axis, ce, cs, np.array([0.3, -0.2, 0.5]), 1.7)
            assert proven and proven_moved, (L, axis, ce, cs, o, w, off)
            assert np.allclose(moved, got, rtol=0.0, atol=1e-9), (moved, got)
            assert len(got) == len(want) and np.allclose(got, want, rtol=0.0, atol=1e-9), (got, want, off)
            total += len(want)
            near += off is not None and sum(abs(x - x0) < 1e-3 for x in want) == 2
    print(eta, lines_in, "lines,", total, "crossings,", near, "pairs within 1e-3 of a touching point")
    assert total > 20 and near > 3  # not vacuous


def twin(tau, k):
    """(G, P, t, cos_t) at tau in mpmath at 30 digits from the geometry: the direction u on the cone at phi(tau)
    (mode 1: sin(phi / 2) = s sin(tau)), its near meeting with the sphere solved from the quadratic,
    Snell's law there."""
    mp = mpmath.mpf
    phi = 2 * mpmath.asin(mp(k.s) * mpmath.sin(tau)) if k.mode == 1 else tau
    u = [mp(k.ce) * mp(k.a[j]) - mp(k.se) * (mpmath.cos(phi) * mp(k.b1[j]) + mpmath.sin(phi) * mp(k.b2[j]))
         for j in range(3)]
    nu = mpmath.sqrt(sum(c * c for c in u))
    u = [c / nu for c in u]
    q = [mp(c) for c in k.q]
    bq = sum(q[j] * u[j] for j in range(3))
    disc = bq * bq - sum(c * c for c in q) + mp(k.radius) ** 2
    P = [q[j] + (-bq - mpmath.sqrt(max(disc, 0))) * u[j] for j in range(3)]
    n = [c / mp(k.radius) for c in P]
    ci = -sum(n[j] * u[j] for j in range(3))
    eta = mp(k.eta)
    ct = mpmath.sqrt(1 - (1 - ci * ci) / (eta * eta))
    t = [u[j] / eta + (ci / eta - ct) * n[j] for j in range(3)]
    m = [mp(k.oc[j]) - P[j] for j in range(3)]
    w = [mp(c) for c in k.w]
    G = w[0] * (t[1] * m[2] - t[2] * m[1]) + w[1] * (t[2] * m[0] - t[0] * m[2]) + w[2] * (t[0] * m[1] - t[1] * m[0])
    return G, P, t, float(ct)


@pytest.mark.parametrize("eta", ETAS)
def test_edge_rays_and_bound(eta):
    """The kernel's edge rays (`edge_ray`, in closed form in the parameter) are the twin's (on the cone,
    the sphere and Snell's law, mpmath) to 1e-12 (the direction and `edge_gap` to 1e-12 + 1e-14 /
    cos_t: a refraction cosine near 0, eta < 1, moves as the root of the rounding of its square), and
    mpmath's second derivative of the twin's G lies within `edge_bound` at random points of random
    cells, in both parametrisations (some edge rays entering, all of them)."""
    mpmath.mp.dps = 30
    rng = np.random.default_rng(11 + int(eta * 10))
    modes, worst = set(), 0.0
    for k in random_cones(rng, eta, 6):
        modes.add(k.mode)
        half = 0.5 * math.pi if k.mode == 1 else math.pi
        for _ in range(4):
            lo, hi = np.sort(rng.uniform(-half, half, 2))
            bound = edge_bound(lo, hi, k)
            for tau in np.linspace(lo, hi, 3):
                G, P, t, ct = twin(mpmath.mpf(tau), k)
                pc, tk = edge_ray(tau, k)
                assert np.allclose(pc, [float(c) for c in P], rtol=0, atol=1e-12), (pc, P)
                assert np.allclose(tk, [float(c) for c in t], rtol=0, atol=1e-12 + 1e-14 / ct), (tk, t, ct)
                assert abs(edge_gap(tau, k) - float(G)) < 1e-12 + 1e-14 / ct
                g2 = abs(float(mpmath.diff(lambda v: twin(v, k)[0], mpmath.mpf(tau), 2)))
                assert g2 <= bound, (tau, lo, hi, g2, bound)
                worst = max(worst, g2 / bound)
    assert modes == {1, 2}, modes
    print(eta, "largest |G''| / bound", worst)


def closed_form(tau, k):
    """G(tau) of `edge_ray`'s closed form in the parameter (mode 1: S and b in cos(tau), phi = 2 asin(s
    sin(tau))) in mpmath at 40 digits, on the record's numbers: the function whose rounding `edge_slope`
    bounds (analytic through the ends of mode 1's range)."""
    mp = mpmath.mpf
    if k.mode == 1:
        cs = mpmath.cos(tau)
        phi = 2 * mpmath.asin(mp(k.s) * mpmath.sin(tau))
        b = -mp(k.beta) - 2 * mp(k.kappa) * cs * cs
        sq = 2 * mp(k.s) * mpmath.sqrt(mp(k.a1)) * cs * mpmath.sqrt(mp(k.beta) + mp(k.kappa) * cs * cs)
    else:
        phi = tau
        b = mp(k.a0) - mp(k.a1) * mpmath.cos(phi)
        sq = mpmath.sqrt((-b - mp(k.beta)) * (mp(k.beta) - b))
    u = [mp(k.ce) * mp(k.a[j]) - mp(k.se) * (mpmath.cos(phi) * mp(k.b1[j]) + mpmath.sin(phi) * mp(k.b2[j]))
         for j in range(3)]
    radius, eta = mp(k.radius), mp(k.eta)
    if k.eta >= 1.0:
        ci = sq / radius
        ct = mpmath.sqrt((eta - 1) * (eta + 1) + ci * ci) / eta
    else:
        ci = mpmath.sqrt((1 - eta) * (1 + eta) + (sq / radius) ** 2)
        ct = sq / (radius * eta)
    pc = [mp(k.q[j]) + (-b - radius * ci) * u[j] for j in range(3)]
    t = [u[j] / eta + (ci / eta - ct) / radius * pc[j] for j in range(3)]
    m = [mp(k.oc[j]) - pc[j] for j in range(3)]
    w = [mp(c) for c in k.w]
    return w[0] * (t[1] * m[2] - t[2] * m[1]) + w[1] * (t[2] * m[0] - t[0] * m[2]) + w[2] * (t[0] * m[1] - t[1] * m[0])


@pytest.mark.parametrize("eta", ETAS)
def test_edge_slope_within_its_rounding(eta):
    """`edge_slope`'s G' differs from mpmath's derivative of the closed form (`closed_form`) by less than
    its rounding bound at random parameters, at the ends of the range (one-sided) and just inside them,
    in both parametrisations; and that derivative is the twin's (from the geometry, `twin`) to 1e-9
    relative away from mode 1's ends, where the closed form's rounded parameters (s, kappa) move the
    twin's grazing ray by a square root of the rounding."""
    mpmath.mp.dps = 40
    rng = np.random.default_rng(23 + int(eta * 10))
    modes, worst = set(), 0.0
    for k in random_cones(rng, eta, 8):
        modes.add(k.mode)
        half = 0.5 * math.pi if k.mode == 1 else math.pi
        for tau in [*rng.uniform(-half, half, 5), -half, half, half * (1.0 - 1e-9), -half * (1.0 - 1e-6)]:
            slope, bound = edge_slope(tau, k)
            side = -1 if tau >= half else 1 if tau <= -half else 0
            ref = mpmath.diff(lambda v: closed_form(v, k), mpmath.mpf(tau), direction=side)
            assert abs(slope - float(ref)) <= bound, (tau, slope, float(ref), bound)
            worst = max(worst, abs(slope - float(ref)) / bound)
            if abs(tau) < 0.99 * half:
                geo = mpmath.diff(lambda v: twin(v, k)[0], mpmath.mpf(tau))
                assert abs(geo - ref) <= 1e-9 * abs(ref) + 1e-13, (tau, float(geo), float(ref))
    assert modes == {1, 2}, modes
    print(eta, "largest |G' error| / bound", worst)
