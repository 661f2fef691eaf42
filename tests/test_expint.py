"""Scaled E1, I0/I1 and the paper's Fig. 2 series against mpmath (30 digits)."""
import math

import mpmath as mp
import pytest

from raytrace.media.expint import en_scaled, g_scaled, i0i1_stable, i01_series, i01_series_est

mp.mp.dps = 30


def _g_ref(w):
    w = mp.mpc(w)
    return complex(mp.exp(w) * mp.e1(w))


def _i_ref(H, va, vb, k):
    f = (lambda v: mp.exp(-H * v) / (1 + v * v)) if k == 0 else (lambda v: mp.exp(-H * v) * v / (1 + v * v))
    hi = mp.inf if vb == math.inf else mp.mpf(vb)
    pts = [mp.mpf(va)] + [p for p in (1, 10) if va < p < vb] + [hi]
    return float(mp.quad(f, pts))


@pytest.mark.parametrize("H", [1e-4, 1e-2, 0.3, 1.0, 7.0, 100.0, 1e3])
def test_g_scaled_vs_mpmath(H):
    for v in [0.0, 1e-3, 0.5, 1.0, 3.0, 30.0, 1e3, 1e6]:
        w = complex(H * v, H)
        ref = _g_ref(w)
        assert abs(g_scaled(w) - ref) <= 1e-13 * abs(ref)


def test_en_scaled():
    for x in [0.0, 1e-3, 0.5, 0.999, 1.0, 4.0, 50.0, 1e4]:
        ref = float(mp.exp(x) * mp.expint(2, x))
        assert en_scaled(2, x) == pytest.approx(ref, rel=1e-13)


@pytest.mark.parametrize("H,va,vb", [(1e-4, 0.0, 1e6), (1e-2, 0.01, 5.0), (0.5, 0.2, math.inf),
                                     (1.0, 0.0, math.inf), (3.0, 1.0, 2.0), (40.0, 0.1, 3.0),
                                     (1e3, 0.0, math.inf), (0.05, 100.0, 1e6)])
def test_i0i1_stable(H, va, vb):
    i0, i1 = i0i1_stable(H, va, vb)
    assert i0 == pytest.approx(_i_ref(H, va, vb, 0), rel=1e-12)
    assert i1 == pytest.approx(_i_ref(H, va, vb, 1), rel=1e-12)


def test_series_accurate_at_small_rho():
    for H, va, vb in [(0.1, 0.2, 5.0), (1.0, 0.0, 3.0), (0.5, 0.0, math.inf), (2.0, 0.3, 2.0)]:
        i0, i1, it = i01_series(-H, va, vb, 1e-12, 200)
        assert i0 == pytest.approx(_i_ref(H, va, vb, 0), rel=1e-9)
        assert 0 < it < 200


def test_series_relative_control_and_iterations_grow_with_rho():
    its = [i01_series(-H, 0.0, 3.0, 1e-3, 500)[2] for H in (0.1, 1.0, 3.0)]
    assert its[0] < its[1] < its[2]


def test_series_documented_failure_at_large_rho():
    # rho_b = H sqrt(1+vb^2) ~ 30: the Fig. 2 series cancels catastrophically, the scaled-E1 form does not
    H, va, vb = 10.0, 1.0, 2.9
    ref = _i_ref(H, va, vb, 0)
    ser, _, _ = i01_series(-H, va, vb, 1e-10, 500)
    stable, _ = i0i1_stable(H, va, vb)
    assert abs(ser / ref - 1.0) > 1e-2          # paper's evaluation wrong
    assert abs(stable / ref - 1.0) < 1e-12      # stable path right
    # and the rounding-error estimate used by the kernel flags it
    _, _, _, est = i01_series_est(-H, va, vb, 1e-10, 500)
    assert est > 1e-2 * abs(ref)
