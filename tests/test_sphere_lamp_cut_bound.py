"""The sphere lamp's surface rule (raytrace/lights/sphere_irradiance.py) on the circles the horizon cuts:
a remainder bound on Bernstein ellipses of the rule's variable (`_cut_ellipses`, `_arc_bound`) picks the
order where it holds, else three orders must agree as before (no bound: inf). Checked:
- the bound bounds: at points near the horizon's cuts (test_sphere_lamp_surface_rule's sampler) and
  spread over the lit caps, kt 0, 0.15 and 3, every order's error against the rule's own integrand in w
  integrated at 32 digits in mpmath is within the bound that order is given (plus n + 8 roundings);
- the irradiance's `bound`: against Snyder's closed form in the vacuum and the 30-digit integral over the
  cap in its polar angle in media (no shared code with the rule), every finite bound holds (plus what
  one rounding of the distance or the angle changes), and it is not vacuous: most points get one, the
  median bound is within the tolerance.
"""
from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest

from raytrace.lights import sphere_irradiance as si

from .test_sphere_lamp_surface import R, snyder
from .test_sphere_lamp_surface_rule import cap_mp, exact_angle, near_cuts, rounding

ULP = 2.0 ** -52


def _geometry(theta: float, d: float):
    """`_geometry` of the point at the origin with normal (sin theta, cos theta, 0), centre (0, d, 0)."""
    return si._geometry(np.array([0.0, d, 0.0]), R, np.zeros(3), np.array([math.sin(theta), math.cos(theta), 0.0]))


def cut_mp(geometry, kt: float):
    """The circles the horizon cuts as the rule integrates them (`_add_cut`: u = u* - w^2, w in [0, sqrt(u*)]),
    with the same float geometry, at 32 digits, split at eta 2^k toward w = 0 (the axis at w = i eta)."""
    cos_t, sin_t, _, cos_a, root_k, _, ustar, eta = geometry
    with mp.workdps(32):
        ct, st, ca, rk, us, k = (mp.mpf(v) for v in (cos_t, sin_t, cos_a, root_k, ustar, kt))

        def f(w):
            u = us - w * w
            c = ca * mp.cosh(u)
            root = mp.sqrt(max(2 * ca * mp.sinh((us + u) / 2) * mp.sinh(w * w / 2) * (st + c), 0))
            a = ct * c
            return 2 * (a * mp.atan2(root, -a) + root) * ca * mp.sinh(u) * 2 * w * mp.exp(-k * rk * mp.exp(-u))

        top, edges = mp.sqrt(us), [mp.mpf(0)]
        step = mp.mpf(eta) / 4 if eta > 0.0 else top
        while step < top:
            edges.append(step)
            step *= 2
        return mp.quad(f, edges + [top])


def _tables(geometry):
    """[(base, damp, count)] of each piece `_add_cut_pieces` integrates."""
    cos_t, sin_t, _, cos_a, _, u0, ustar, eta = geometry
    top = math.sqrt(ustar)
    split = si.KAPPA * top < eta < si.SPLIT * top
    out = []
    for lo, hi, sinh_t in ([(0.0, si.SPLIT * top, True), (si.SPLIT * top, top, False)] if split else
                           [(0.0, top, False)]):
        base, damp = np.empty(si.CUT_RHOS), np.empty(si.CUT_RHOS)
        out.append((base, damp, si._cut_ellipses(cos_t, sin_t, cos_a, ustar, u0, eta, lo, hi, sinh_t, base, damp)))
    return out


def _spread(seed: int, count: int):
    """(theta, d): d log-uniform over 1.0005 to 30 radii, theta uniform over the normals whose horizon cuts
    the cap."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        d = R * math.exp(rng.uniform(math.log(1.0005), math.log(30.0)))
        alpha = math.asin(R / d)
        out.append((math.pi / 2 + rng.uniform(-alpha, alpha), d))
    return out


@pytest.mark.parametrize("kt", [0.0, 0.15, 3.0])
def test_the_remainder_bounds_the_rule(kt):
    """120 points, every order of ORDERS: its error within its bound; most points have a finite bound at
    64 nodes."""
    finite = 0
    cases = near_cuts(8, 60) + _spread(9, 60)
    for theta, d in cases:
        g = _geometry(theta, d)
        if not g[6] > 0.0:
            continue
        want = float(cut_mp(g, kt))
        tables = _tables(g)
        for k, n in enumerate(si.ORDERS):
            acc = np.zeros(3)
            si._add_cut_pieces(acc, si.NODES[si.OFFSETS[k]:si.OFFSETS[k + 1]],
                               si.WEIGHTS[si.OFFSETS[k]:si.OFFSETS[k + 1]], np.full(3, kt), *[g[i] for i in
                                                                                         (0, 1, 3, 4, 6, 5, 7)])
            bound = sum(si._cut_bound(base, damp, count, kt * g[4], n) for base, damp, count in tables)
            assert abs(acc[0] - want) <= bound + (n + 8) * ULP * abs(want), (theta, d, kt, n, acc[0] - want, bound)
        finite += bound < 1e-12 * abs(want)
    assert finite >= 0.75 * len(cases), finite


def _check(cases, kt, ref, tol):
    """(bounded, [bound / (tol E)]) of the irradiance at `cases`: every finite bound holds against `ref`."""
    ratios = []
    for theta, d in cases:
        th, length = exact_angle(theta)
        want = float(ref(th, d) * length)
        if want == 0.0:
            continue
        bound, missed = np.zeros((1, 3)), np.zeros(1)
        n = np.array([[math.sin(theta), math.cos(theta), 0.0]])
        e = si.irradiance([0.0, d, 0.0], R, np.ones(3), np.zeros((1, 3)), n, np.full(3, kt), tol, missed, bound)
        slack = 2.0 * rounding(th, d) * abs(want)
        assert abs(e[0, 0] - want) <= bound[0, 0] + slack, (theta, d, kt, tol, e[0, 0] / want - 1.0, bound[0, 0])
        ratios.append(bound[0, 0] / (tol * want))
    return ratios


@pytest.mark.parametrize("tol", [1e-6, 1e-10])
def test_the_bound_holds_in_the_vacuum(tol):
    """400 points near the horizon's cuts and over the lit caps against Snyder's closed form."""
    ratios = _check(near_cuts(10, 200) + _spread(11, 200), 0.0, lambda th, d: snyder(th, d, R), tol)
    assert np.mean(np.isfinite(ratios)) >= 0.75 and np.median(ratios) <= 1.0, (np.mean(np.isfinite(ratios)),
                                                                               np.median(ratios))


@pytest.mark.parametrize("kt", [0.15, 3.0])
def test_the_bound_holds_in_a_medium(kt):
    """40 points against the 30-digit integral over the cap."""
    ratios = _check(near_cuts(12, 20) + _spread(13, 20), kt, lambda th, d: cap_mp(th, d, R, kt), 1e-10)
    assert np.mean(np.isfinite(ratios)) >= 0.75 and np.median(ratios) <= 1.0, (np.mean(np.isfinite(ratios)),
                                                                               np.median(ratios))
