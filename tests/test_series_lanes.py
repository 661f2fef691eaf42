"""`i01_series_lanes` (the paper's Fig. 2 loops of many segments side by side, `analytic`'s batch of HG
segments) against 30-digit mpmath and against the scalar loop `i01_series_est`: I0 and I1 within the requested
precision wherever the kernel's guard accepts the loop, the same iteration counts (the loop's own stopping test,
lane by lane), results that do not depend on the batch, and the whole batched kernel (`evaluate_deferred`, HG
0.9, the loops and the moment recurrences deferred) against the mpmath oracle of the defining integral."""
import math

import numpy as np
import pytest

from raytrace.media.expint import EULER_GAMMA, LIBM_ULPS, SERIES_LANES, i01_series_est, i01_series_lanes
from raytrace.media.phase import HG
from raytrace.methods import analytic as A
from raytrace.methods.geometry import POINT_ROW

from .test_analytic_kernels import _oracle
from .test_expint import _i_ref


def _cases(n, seed, rho_max=A.RHO_SWITCH_CAP):
    """(H, va, vb, precision) rows with rho_b = H sqrt(1 + vb^2) <= rho_max (the series' range in `analytic`),
    a fifth of them to vb = inf (rho_b 0 there)."""
    rng = np.random.default_rng(seed)
    va = rng.uniform(0.0, 3.0, n)
    vb = va + 10.0 ** rng.uniform(-2.0, 1.5, n)
    H = np.minimum(10.0 ** rng.uniform(-3.0, 1.0, n), 0.999 * rho_max / np.sqrt(1.0 + vb * vb))
    vb[rng.random(n) < 0.2] = math.inf
    return np.column_stack([H, va, vb, 10.0 ** rng.uniform(-12.0, -2.0, n)])


def _lanes(args, rows=None, max_iter=1000):
    rows = np.arange(len(args)) if rows is None else rows
    out = np.empty((len(rows), 4))
    i01_series_lanes(args, rows, 3, max_iter, out)
    return out


def _accepted(i0, err, precision):
    """`analytic`'s guard on a loop's result (SERIES_SAFETY of the precision)."""
    return err <= A.SERIES_SAFETY * precision * i0


def test_lanes_vs_mpmath():
    args = _cases(60, 1)
    out = _lanes(args)
    checked = 0
    for (H, va, vb, prec), (i0, i1, it, err) in zip(args, out):
        if not _accepted(i0, err, prec):
            continue
        checked += 1
        r0, r1 = _i_ref(H, va, vb, 0), _i_ref(H, va, vb, 1)
        # the relative control stops once the next terms are below prec |I0| (measured: 0.08 prec |I0|); rounding
        # adds at most err
        assert abs(i0 - r0) <= prec * abs(r0) + err, (H, va, vb, prec, i0, r0)
        assert abs(i1 - r1) <= prec * abs(r0) + err, (H, va, vb, prec, i1, r1)
    assert checked >= 40


def test_lanes_stop_where_the_scalar_loop_stops():
    args = _cases(2000, 2)
    for max_iter in (1000, 5, 4, 1, 0):
        out = _lanes(args, max_iter=max_iter)
        for (H, va, vb, prec), (i0, i1, it, err) in zip(args, out):
            ref = i01_series_est(-H, va, vb, prec, max_iter)
            assert it == ref[2]
            if _accepted(i0, err, prec):
                # the same terms, rounded otherwise (fused multiply-adds, libmvec): within the rounding estimate,
                # the scalar loop's plus the allowance for libmvec (no absolute tolerance: the estimates are ~1e-14)
                assert abs(i0 - ref[0]) <= err and abs(i1 - ref[1]) <= err
                assert err == pytest.approx(ref[3] + _libm_allowance(H, va, vb), rel=1e-9, abs=0.0)


def _libm_allowance(H, va, vb):
    """`i01_series_lanes`' allowance for libmvec's error in the loop's start terms: 2 LIBM_ULPS eps times the
    magnitudes of the logarithm and the angle (at vb = inf plus gamma and pi)."""
    if vb < math.inf:
        ends = abs(math.log(math.sqrt(1.0 + vb * vb) / math.sqrt(1.0 + va * va)))
        ends += abs(math.atan((va - vb) / (1.0 + va * vb)))
    else:
        ends = abs(math.log(H * math.sqrt(1.0 + va * va))) + abs(0.5 * math.pi + math.atan(va)) + EULER_GAMMA + math.pi
    return 2.0 * LIBM_ULPS * 2.220446049250313e-16 * ends


def test_lanes_whatever_the_batch():
    args = _cases(3 * SERIES_LANES + 5, 3)
    out = _lanes(args)
    rng = np.random.default_rng(4)
    for rows in (rng.permutation(len(args)), np.arange(7), np.array([11, 11, 3]), np.arange(len(args))[::-1]):
        assert np.array_equal(_lanes(args, rows), out[rows])


@pytest.mark.parametrize("precision", [1e-3, 1e-6])
def test_deferred_hg_kernel_vs_oracle(precision):
    """HG 0.9 segments of rays past a light (rho <= 16: the series path, its loops and recurrences deferred)."""
    rng = np.random.default_rng(5)
    n = 40
    xh, h = rng.uniform(-2.0, 6.0, n), 10.0 ** rng.uniform(-1.5, 0.5, n)
    ell = rng.uniform(0.5, 8.0, n)
    ell[::5] = math.inf
    da = np.hypot(xh, h)
    kt, ks = 0.35, 0.3
    wp = A.working_precision(precision)
    coeffs = A.make_coeffs(HG, 0.9, A.ANISO_EXACT, 6, wp)
    out, met, stats = np.empty(n), np.empty(n, dtype=np.bool_), A.new_stats()
    A.evaluate_deferred(xh, h, da, ell, kt, ks, HG, 0.9, wp, 1000, A.ANISO_EXACT, 6, coeffs,
                        np.tile(np.array(POINT_ROW), (n, 1)), out, met, stats)
    assert stats[A.ST_SERIES] >= 0.8 * n and met.all()
    for s in range(n):
        ref = _oracle(xh[s], h[s], ell[s], kt, ks, HG, 0.9)
        assert abs(out[s] - ref) <= precision * abs(ref), (s, out[s], ref)
