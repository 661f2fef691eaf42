"""Cosine-moment recurrence of the exact anisotropic air-light (raytrace/media/legendre_moments.py)
against mpmath quadrature in phi, inside its stability region (H * L moderate)."""
import math

import mpmath as mp
import numpy as np
import pytest

from raytrace.media.expint import g_scaled
from raytrace.media.legendre_moments import (FORWARD_ERR_PER_LOSS, LANES, cosine_moments_forward,
                                             cosine_moments_lanes, forward_loss, hg_legendre, legendre_to_cosine,
                                             rayleigh_legendre)


# Absolute cap on the error bounds below, which the code under test computes (its loss estimate
# forward_loss times FORWARD_ERR_PER_LOSS): however large that estimate grows, the recurrence must
# deliver, inside the stability region tested here, the finest working precision `analytic` asks
# of it: 1e-11 (working_precision(1e-8)). Measured worst: 1.2e-12 (HG g = 0.9, H = 0.3, va = 20),
# 6.2e-15 (Rayleigh); uncapped, the bounds reach 2e-6 and 1e-7.
CAP = 1e-11


def _inputs(H, va, vb):
    """K1, L1, ea, eb scaled by F = e^{H va}."""
    ga = g_scaled(complex(H * va, H))
    K1, L1, eb = -ga.imag, ga.real, 0.0
    if vb < math.inf:
        eb = math.exp(-H * (vb - va))
        gb = g_scaled(complex(H * vb, H))
        K1 += eb * gb.imag
        L1 -= eb * gb.real
    return K1, L1, 1.0, eb


def _ref(H, va, vb, c):
    """e^{H va} int_{phia}^{phib} e^{-H tan(phi/2)} sum c_k cos(k phi) dphi, 30 digits."""
    with mp.workdps(30):
        cs = [mp.mpf(float(x)) for x in c]
        pa = 2 * mp.atan(mp.mpf(va))
        pb = mp.pi if vb == math.inf else 2 * mp.atan(mp.mpf(vb))
        Hm = mp.mpf(H)

        def f(p):
            if p >= mp.pi:
                return mp.mpf(0)
            x = Hm * (mp.tan(p / 2) - va)
            if x > 800:
                return mp.mpf(0)
            return mp.exp(-x) * sum(ck * mp.cos(k * p) for k, ck in enumerate(cs))

        # breakpoints geometric in the optical depth from phia (peaked integrand for large H)
        pts = [pa]
        for d in (0.05, 0.2, 1.0, 3.0, 10.0, 30.0):
            p = 2 * mp.atan(va + d / Hm)
            if pts[-1] < p < pb:
                pts.append(p)
        pts.append(pb)
        return float(mp.quad(f, pts))


@pytest.mark.parametrize("g,L", [(0.9, 120), (-0.5, 27), (0.5, 27)])
@pytest.mark.parametrize("H", [1e-4, 0.05, 0.3])
@pytest.mark.parametrize("va,vb", [(0.0, math.inf), (0.3, 2.0), (20.0, math.inf), (0.01, 0.02)])
def test_hg_vs_mpmath(g, L, H, va, vb):
    c = legendre_to_cosine(hg_legendre(g, L))
    K1, L1, ea, eb = _inputs(H, va, vb)
    s = cosine_moments_forward(H, va, vb, K1, L1, ea, eb, c)
    r = _ref(H, va, vb, c)
    # rounding grows like the recurrence's loss estimate times the cancellation of the final sum
    bound = max(1e-12, 30 * FORWARD_ERR_PER_LOSS * forward_loss(H, c) * np.abs(c).sum() / abs(r))
    assert abs(s / r - 1.0) < min(bound, CAP)
    assert bound < 1e-5


def test_lanes_vs_mpmath_whatever_the_batch():
    """The batched recurrence (`cosine_moments_lanes`) against mpmath, within the bound of
    test_hg_vs_mpmath, on rows that fill more than one group of LANES; each row's result is the same
    bit for bit in any other batch (reversed, alone)."""
    c = legendre_to_cosine(hg_legendre(0.9, 120))
    cases = [(H, va, vb) for H in (1e-4, 0.05, 0.3) for va, vb in [(0.0, math.inf), (0.3, 2.0), (20.0, math.inf),
                                                                     (0.01, 0.02)]]
    args = np.array([(H, va, vb, *_inputs(H, va, vb)) for H, va, vb in cases])
    rows = np.arange(LANES + 5) % len(cases)
    out = np.empty(len(rows))
    cosine_moments_lanes(args, rows, c, out)
    for (H, va, vb), s in zip(cases, out):
        r = _ref(H, va, vb, c)
        bound = max(1e-12, 30 * FORWARD_ERR_PER_LOSS * forward_loss(H, c) * np.abs(c).sum() / abs(r))
        assert abs(s / r - 1.0) < min(bound, CAP)
    back = np.empty(len(rows))
    cosine_moments_lanes(args, rows[::-1].copy(), c, back)
    assert np.array_equal(back[::-1], out)
    for i in range(len(cases)):
        one = np.empty(1)
        cosine_moments_lanes(args, np.array([i]), c, one)
        assert one[0] == out[i] == out[i + len(cases)]


@pytest.mark.parametrize("n", range(1, 10))
def test_lanes_every_length_vs_mpmath(n):
    """`cosine_moments_lanes` on series of every length from 1 to 9 terms (no step of the recurrence, one,
    several) against mpmath, as test_lanes_vs_mpmath_whatever_the_batch."""
    c = legendre_to_cosine(hg_legendre(0.5, n - 1))
    cases = [(0.05, 0.3, 2.0), (0.3, 0.0, math.inf)]
    args = np.array([(H, va, vb, *_inputs(H, va, vb)) for H, va, vb in cases])
    out = np.empty(len(cases))
    cosine_moments_lanes(args, np.arange(len(cases)), c, out)
    for (H, va, vb), s in zip(cases, out):
        r = _ref(H, va, vb, c)
        bound = max(1e-12, 30 * FORWARD_ERR_PER_LOSS * forward_loss(H, c) * np.abs(c).sum() / abs(r))
        assert abs(s / r - 1.0) < min(bound, CAP), (n, H, va, vb, s, r)


def test_forward_loss_grows_with_H():
    c = legendre_to_cosine(hg_legendre(0.7, 50))
    losses = [forward_loss(H, c) for H in (0.01, 0.1, 1.0, 10.0)]
    assert losses == sorted(losses) and losses[-1] > 1e3 * losses[0]


def test_cosine_conversion():
    a = hg_legendre(0.6, 12)
    c = legendre_to_cosine(a)
    for mu in np.linspace(-1, 1, 7):
        phi = math.acos(mu)
        lhs = np.polynomial.legendre.legval(mu, a)
        rhs = sum(ck * math.cos(k * phi) for k, ck in enumerate(c))
        assert abs(lhs - rhs) < 1e-13 * abs(lhs)


@pytest.mark.parametrize("H,va,vb", [(0.01, 0.0, math.inf), (0.5, 0.3, 2.0), (4.0, 1.0, math.inf), (20.0, 0.2, 0.9)])
def test_rayleigh_exact(H, va, vb):
    a = rayleigh_legendre()
    assert np.allclose(a, [1 / (4 * math.pi), 0.0, 1 / (8 * math.pi)])
    c = legendre_to_cosine(a)
    assert np.allclose(c, 3 / (16 * math.pi) * np.array([1.5, 0.0, 0.5]))
    K1, L1, ea, eb = _inputs(H, va, vb)
    s = cosine_moments_forward(H, va, vb, K1, L1, ea, eb, c)
    with mp.workdps(30):
        f = lambda v: mp.exp(-H * (v - va)) * 2 / (1 + v * v) * 3 / (16 * mp.pi) * (1 + ((1 - v * v) / (1 + v * v)) ** 2)
        end = mp.inf if vb == math.inf else vb
        r = float(mp.quad(f, [va, va + 1 / H, end] if va + 1 / H < end else [va, end]))
    assert abs(s / r - 1.0) < min(1e-12 * forward_loss(H, c), CAP)
