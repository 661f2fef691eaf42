"""The Fig. 2 series (`expint.i01_series_est`) used up to rho = 16 (`analytic.RHO_SWITCH_CAP`), against
30-digit mpmath and a plain twin of the paper's loop."""
import math

import mpmath as mp
import numpy as np
import pytest

from raytrace.media.expint import i01_series_est
from raytrace.methods import analytic as A
from raytrace.methods.geometry import POINT_ROW
from raytrace.media.phase import INV_4PI, ISOTROPIC

mp.mp.dps = 30


def _i_ref(H, va, vb):
    """(I0, I1) = int_va^vb e^{-Hv} (1, v) / (1 + v^2) dv by mpmath."""
    hi = mp.inf if vb == math.inf else mp.mpf(vb)
    pts = [mp.mpf(va)] + [p for p in (1, 10) if va < p < vb] + [hi]
    return tuple(float(mp.quad(lambda v, j=j: mp.exp(-H * v) * v ** j / (1 + v * v), pts)) for j in (0, 1))


def _segments(lo, hi, n, seed):
    """n (H, va, vb) with rho_b = H sqrt(1 + vb^2) in (lo, hi], angles uniform."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        H = math.exp(rng.uniform(math.log(0.05), math.log(30.0)))
        a, b = np.sort(rng.uniform(0.0, math.pi, 2))
        va, vb = math.tan(a / 2), math.tan(b / 2)
        if lo < H * math.sqrt(1.0 + vb * vb) <= hi:
            out.append((H, va, vb))
    return out


def _paper_loop(a, va, vb, precision):
    """(I0, iterations) of the paper's Fig. 2 loop in plain Python: its log and angle terms from math.atan2,
    then rho^k sin(a - k phi) / (k k!) at both ends by complex powers, stopping after the first term whose
    indicator (rho_b^k + rho_a^k) / (k k!) is <= precision |I0|."""
    z = [complex(a * va, -a), complex(a * vb, -a)]
    e = complex(math.cos(a), math.sin(a))
    logv = 0.5 * math.log((1.0 + vb * vb) / (1.0 + va * va))
    i0 = math.sin(a) * logv - math.cos(a) * math.atan2(va - vb, 1.0 + va * vb)
    p = [e, e]
    r = [abs(a) * math.sqrt(va * va + 1.0), abs(a) * math.sqrt(vb * vb + 1.0)]
    rk = [1.0, 1.0]
    kfac = 1.0
    for k in range(1, 1000):
        kfac *= k
        p = [p[0] * z[0], p[1] * z[1]]
        rk = [rk[0] * r[0], rk[1] * r[1]]
        i0 += (p[1].imag - p[0].imag) / (k * kfac)
        if (rk[0] + rk[1]) / (k * kfac) <= precision * abs(i0):
            return i0, k
    return i0, 1000


@pytest.mark.parametrize("precision", [1e-3, 1e-6, 1e-10])
def test_the_kernel_loop_is_the_papers(precision):
    """The kernel's loop (tabulated weights, the angle by atan of a quotient) sums the same terms as the
    paper's loop and agrees with it to the rounding of the larger terms."""
    for H, va, vb in _segments(0.0, 16.0, 60, 1):
        i0, _, k, err = i01_series_est(-H, va, vb, precision, 1000)
        ref, k_ref = _paper_loop(-H, va, vb, precision)
        assert k == k_ref and abs(i0 - ref) <= err, (H, va, vb)


@pytest.mark.parametrize("precision", [1e-3, 1e-6])
def test_accepted_series_meets_the_precision_up_to_rho_16(precision):
    """Where the kernel's guard accepts the series (rounding estimate <= precision / 10, converged),
    I0 and I1 are within the precision of I0 (the truncation, the paper's relative control, measured
    below 0.25 precision); most of them are accepted at rho 8-16."""
    accepted = 0
    segs = _segments(8.0, 16.0, 40, 2)
    for H, va, vb in segs:
        i0, i1, k, err = i01_series_est(-H, va, vb, precision, 1000)
        if not (k < 1000 and err <= A.SERIES_SAFETY * precision * i0):
            continue
        accepted += 1
        r0, r1 = _i_ref(H, va, vb)
        assert abs(i0 - r0) <= precision * r0 and abs(i1 - r1) <= precision * r0, (H, va, vb)
    assert accepted >= 0.5 * len(segs)


def test_rounding_estimate_bounds_the_rounding_up_to_rho_20():
    """The series summed to full convergence (no truncation) differs from mpmath by less than its
    rounding-error estimate (measured 0.07-0.11 of it at rho 4-20)."""
    for lo, hi in ((4.0, 8.0), (8.0, 12.0), (12.0, 16.0), (16.0, 20.0)):
        for H, va, vb in _segments(lo, hi, 10, 3):
            i0, i1, k, err = i01_series_est(-H, va, vb, 1e-200, 1000)
            r0, r1 = _i_ref(H, va, vb)
            assert max(abs(i0 - r0), abs(i1 - r1)) <= 0.5 * err, (H, va, vb)


def test_kernel_takes_the_series_up_to_rho_16():
    """Isotropic segments with rho near 16 on the series path at precision 1e-3 (the default), their
    values within the precision of the mpmath integral (I0 folded: Lm = 2 I ks / h e^{-kt xh} I0 / (4 pi))."""
    co = A.make_coeffs(ISOTROPIC, 0.0, A.ANISO_EXACT, 1, 1e-3)
    for xh, h, ell, kt in ((1.0, 2.0, 6.0, 1.5), (3.0, 1.0, 6.0, 2.5), (-2.0, 3.0, 4.0, 1.2)):
        H = kt * h
        va = A.v_of(-xh, h)
        vb = A.v_of(ell - xh, h)
        assert 15.0 < H * math.sqrt(1.0 + vb * vb) <= A.RHO_SWITCH_CAP
        stats = A.new_stats()
        da = math.hypot(xh, h)
        val = A.airlight(xh, h, da, ell, kt, 0.5 * kt, 1.0, ISOTROPIC, 0.0, 1e-3, 1000, 0, 1, co, POINT_ROW, stats)
        assert stats[A.ST_SERIES] == 1.0 and stats[A.ST_STABLE] == 0.0
        ref = 2.0 / h * 0.5 * kt * INV_4PI * math.exp(-kt * xh) * _i_ref(H, va, vb)[0]
        assert abs(val - ref) <= 1e-3 * ref
