"""The sphere lamp's surface rule (raytrace/lights/sphere_irradiance.py) in a medium where the cap it
fills lies wholly above the point's horizon: its circles' integral in u is entire and the rule's order
comes from a remainder bound on a Bernstein ellipse (`_remainder`), not from agreeing orders. Checked:
- the bound bounds: on 300 random pieces [u*, u0] (1.0005 to 30 radii, kt sqrt(d^2 - R^2) from 1e-3 to
  100, u* from 0 to u0), each order's error against a 30-digit Gauss–Legendre integral in mpmath (20
  panels) is within every remainder (of the piece times 10^-k/4) that `_needed` says its nodes reach,
  plus (n + 4 + 2 kt sqrt(d^2 - R^2)) roundings of the piece (the sum's and the exponent's), and the
  rule's lower bound is one;
- points whose cap lies wholly above the horizon, 1.0005 to 30 radii from the sphere, in media (kt 0.15
  and 3), against the 30-digit integral over the cap in its polar angle beta (mpmath's tanh-sinh, no
  shared code or variable with the rule): none counted, none beyond its tolerance (1e-6, 1e-10, 1e-12)
  plus two roundings; 300 points here, 3,000 in the slow test.
"""
from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest

from raytrace.lights import sphere_irradiance as si

from .test_sphere_lamp_surface import R
from .test_sphere_lamp_surface_rule import check

TOLS = (1e-6, 1e-10, 1e-12)


def above_mp(theta, d: float, kt: float):
    """E / L of a cap wholly above the horizon: 2 pi cos theta int_0^alpha exp(-kt s(beta)) cos beta sin beta
    dbeta (Phi = 2 pi cos theta cos beta), s(beta) = d cos beta - sqrt(R^2 - d^2 sin^2 beta), at 30 digits."""
    with mp.workdps(30):
        th, d, r, kt = mp.mpf(theta), mp.mpf(d), mp.mpf(R), mp.mpf(kt)

        def f(b):
            s = d * mp.cos(b) - mp.sqrt(max(0, r * r - (d * mp.sin(b)) ** 2))
            return mp.exp(-kt * s) * mp.cos(b) * mp.sin(b)

        return 2 * mp.pi * mp.cos(th) * mp.quad(f, [0, mp.asin(r / d)])


def wholly_above(seed: int, count: int):
    """(theta, d): d log-uniform over 1.0005 to 30 radii, theta uniform over the normals whose plane leaves
    the cap wholly above (theta < pi/2 - alpha), a tenth of them within 1e-6 alpha of that edge."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        d = R * math.exp(rng.uniform(math.log(1.0005), math.log(30.0)))
        edge = math.pi / 2 - math.asin(R / d)
        out.append((edge * (1.0 - 1e-6 * rng.uniform()) if i % 10 == 0 else edge * rng.uniform(), d))
    return out


def test_the_remainder_bounds_the_rule():
    rng = np.random.default_rng(21)
    for _ in range(300):
        d = R * math.exp(rng.uniform(math.log(1.0005), math.log(30.0)))
        root_k = math.sqrt((d - R) * (d + R))
        u0 = 0.5 * math.log1p(2.0 * R / (d - R))
        ustar = u0 * rng.uniform() ** 2
        kt = math.exp(rng.uniform(math.log(1e-3), math.log(100.0))) / root_k
        with mp.workdps(30):
            g = lambda u: mp.cosh(u) * mp.sinh(u) * mp.exp(-kt * root_k * mp.exp(-u))  # noqa: E731
            want = mp.quad(g, mp.linspace(ustar, u0, 21), method="gauss-legendre")
        for k in range(len(si.ORDERS)):
            lo, hi = si.OFFSETS[k], si.OFFSETS[k + 1]
            got, lower = si._above_rule(kt, root_k, ustar, u0 - ustar, si.NODES[lo:hi], si.WEIGHTS[lo:hi])
            err = abs(got - float(want))
            rounding = (hi - lo + 4 + 2 * kt * root_k) * 2.0 ** -52 * abs(float(want))  # the sum's and the exponent's
            assert lower <= float(want) * (1.0 + 1e-15)
            bound = min(t for t in float(want) * 10.0 ** -np.arange(0.0, 17.0, 0.25)
                        if si._needed(kt, root_k, ustar, u0, math.log(t)) <= hi - lo or t == float(want))
            assert err <= bound + rounding, (d, ustar, kt, k, err, bound)


@pytest.mark.parametrize("kt", [0.15, 3.0])
def test_caps_above_the_horizon_within_their_tolerance(kt):
    assert check(wholly_above(31, 150), kt, lambda th, d: above_mp(th, d, kt), TOLS) == 0


@pytest.mark.slow
@pytest.mark.parametrize("kt", [0.15, 3.0])
def test_caps_above_the_horizon_within_their_tolerance_many(kt):
    assert check(wholly_above(32, 1500), kt, lambda th, d: above_mp(th, d, kt), TOLS) == 0
