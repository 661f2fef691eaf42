"""Air-light kernels vs an independent mpmath quadrature of the defining integral (PP-4)."""
import math
from functools import lru_cache

import mpmath as mp
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from raytrace.methods.geometry import POINT_ROW
from raytrace.methods import analytic as A
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH


def _phase_mp(code, g, mu):
    if code == ISOTROPIC:
        return 1 / (4 * mp.pi)
    if code == RAYLEIGH:
        return 3 / (16 * mp.pi) * (1 + mu * mu)
    den = 1 + g * g - 2 * g * mu
    return (1 - g * g) / (4 * mp.pi * den * mp.sqrt(den))


def _oracle(xh, h, ell, kt, ks, code, g, phase=None):
    """mpmath.quad over x with breakpoints around the light's foot point and the extinction scale."""
    with mp.workdps(20):
        xh_, h_, kt_, g_ = mp.mpf(xh), mp.mpf(h), mp.mpf(kt), mp.mpf(g)

        def f(x):
            s = x - xh_
            d = mp.sqrt(h_ * h_ + s * s)
            ph = _phase_mp(code, g_, -s / d) if phase is None else phase(s, d)
            return mp.exp(-kt_ * (x + d)) * ks * ph / (d * d)

        pts = {mp.mpf(0)}
        for m in (0, 0.3, 1, 3, 10, 30, 100, 1000):
            pts.update((xh_ - m * h_, xh_ + m * h_))
        for m in (1, 3, 10, 30):
            pts.add(mp.mpf(m) / kt_)
        end = mp.inf if ell == math.inf else mp.mpf(ell)
        p = sorted(x for x in pts if x >= 0 and (end == mp.inf or x < end)) + [end]
        return float(mp.quad(f, p))


def _geom(light):
    p = np.asarray(light, float)
    d = np.array([1.0, 0.0, 0.0])
    xh = float(p @ d)
    return xh, float(np.linalg.norm(p - xh * d)), float(np.linalg.norm(p))


# (light position, ell, kt): thin/thick, behind the camera, near the axis, ell = inf
CASES = [
    ((2.0, 1.0, 0.0), 5.0, 0.1),        # thin, light beside the segment
    ((2.0, 0.5, 0.0), math.inf, 2.0),   # thick, ell = inf (optical depth inf)
    ((-3.0, 1.0, 0.0), 4.0, 0.5),       # light behind the camera
    ((-30.0, 2.0, 0.0), math.inf, 1.0),  # far behind, would overflow e^{kt(xa-xh)}
    ((5.0, 0.01, 0.0), 3.0, 0.3),       # light ahead, near the axis
    ((1.0, 3.0, 0.0), 2.0, 5.0),        # thick (tau = 10 along the view), rho large
    ((10.0, 0.2, 0.0), 20.0, 1.5),      # optical depth 30 along the view
    ((-2.0, 1e-7, 0.0), 3.0, 0.7),      # on the line behind the camera (near-line path)
    ((6.0, 1e-8, 0.0), 3.0, 0.7),       # on the line ahead of the segment (near-line path)
]
PHASES = [(ISOTROPIC, 0.0), (RAYLEIGH, 0.0), (HG, -0.5), (HG, 0.5), (HG, 0.9), (HG, 0.95)]


@lru_cache(maxsize=None)
def _ref(ci, code, g):
    light, ell, kt = CASES[ci]
    xh, h, _ = _geom(light)
    return _oracle(xh, h, ell, kt, 0.8 * kt, code, g)


@pytest.mark.parametrize("code,g", PHASES)
def test_kernel_vs_oracle(code, g):
    for prec in (1e-3, 1e-5, 1e-8):
        co = A.make_coeffs(code, g, A.ANISO_EXACT, 6, prec)
        stats = A.new_stats()
        for ci, (light, ell, kt) in enumerate(CASES):
            xh, h, da = _geom(light)
            val = A.airlight(xh, h, da, ell, kt, 0.8 * kt, 2.0, code, g, prec, 1000, A.ANISO_EXACT, 6, co, POINT_ROW, stats)
            ref = 2.0 * _ref(ci, code, g)
            assert math.isfinite(val) and val >= 0.0
            assert abs(val / ref - 1.0) <= 10 * prec, (code, g, prec, CASES[ci], val, ref)
        n = len(CASES)
        assert stats[A.ST_EVALS] == n and stats[A.ST_NEARLINE] == 2
        assert stats[A.ST_SERIES] + stats[A.ST_STABLE] + stats[A.ST_NEARLINE] + stats[A.ST_FALLBACK] == n
        s = A.summarize_stats(stats)
        assert s["evaluations"] == n and s["near_line_fraction"] == pytest.approx(2 / n)
        assert s["series_fraction"] + s["stable_fraction"] + s["near_line_fraction"] + s["fallback_fraction"] \
            == pytest.approx(1.0)


@pytest.mark.parametrize("code,g", [(RAYLEIGH, 0.0), (HG, -0.5), (HG, 0.9)])
def test_batched_kernel_vs_oracle_whatever_the_batch(code, g):
    """`evaluate_deferred` (a batch: the exact mode's recurrences run after the loop, block by block,
    `cosine_moments_lanes`) against the oracle as test_kernel_vs_oracle and within a hundredth of the
    precision of one call per segment (the two recurrences round differently, and the thick cases'
    loss amplifies that to 5e-12 relative), the statistics those of one call per segment, and each
    segment's value bit for bit the same in a reversed batch and alone."""
    idx = np.arange(70) % len(CASES)  # more rows than one group of lanes
    geo = np.array([(*_geom(CASES[i][0]), CASES[i][1]) for i in idx])
    kts = {CASES[i][2] for i in idx}
    for prec in (1e-3, 1e-8):
        co = A.make_coeffs(code, g, A.ANISO_EXACT, 6, prec)
        for kt in kts:
            rows = [i for i in range(len(idx)) if CASES[idx[i]][2] == kt]

            def batch(order):
                xh, h, da, ell = (np.ascontiguousarray(geo[order, j]) for j in range(4))
                out, met, stats = np.empty(len(order)), np.empty(len(order), dtype=np.bool_), A.new_stats()
                A.evaluate_deferred(xh, h, da, ell, kt, 0.8 * kt, code, g, prec, 1000, A.ANISO_EXACT, 6, co,
                                    np.tile(POINT_ROW, (len(order), 1)), out, met, stats, spots=False)
                return out, met, stats

            out, met, stats = batch(np.array(rows))
            one = A.new_stats()
            for r, val in zip(rows, out):
                xh, h, da, ell = geo[r]
                assert val == pytest.approx(A.airlight(xh, h, da, ell, kt, 0.8 * kt, 1.0, code, g, prec, 1000,
                                                       A.ANISO_EXACT, 6, co, POINT_ROW, one), rel=0.01 * prec, abs=0.0)
                assert abs(val / (_ref(idx[r], code, g)) - 1.0) <= 10 * prec
                alone = batch(np.array([r]))[0][0]
                assert alone == val
            assert met.all() and np.array_equal(stats, one)
            back = batch(np.array(rows[::-1]))[0]
            assert np.array_equal(back[::-1], out)


def test_batched_taylor_mode_is_one_call_per_segment():
    """The Taylor mode through `evaluate_deferred` (its coefficients are no blocks: nothing is left
    to the batched recurrence) gives what one call per segment gives."""
    co = A.make_coeffs(HG, 0.9, A.ANISO_TAYLOR, 6, 1e-3)
    assert co.min() < -1.0  # large negative coefficients, which read as block lengths would misguide a walk
    for light, ell, kt in CASES:
        xh, h, da = _geom(light)
        out, met, stats = np.empty(1), np.empty(1, dtype=np.bool_), A.new_stats()
        A.evaluate_deferred(np.array([xh]), np.array([h]), np.array([da]), np.array([ell]), kt, 0.8 * kt, HG, 0.9,
                            1e-3, 1000, A.ANISO_TAYLOR, 6, co, POINT_ROW[None, :], out, met, stats, spots=False)
        one = A.airlight(xh, h, da, ell, kt, 0.8 * kt, 1.0, HG, 0.9, 1e-3, 1000, A.ANISO_TAYLOR, 6, co, POINT_ROW,
                         A.new_stats())
        assert out[0] == one


def test_paths_are_exercised():
    stats = A.new_stats()
    co = A.make_coeffs(ISOTROPIC, 0.0, A.ANISO_EXACT, 1, 1e-6)
    for light, ell, kt in CASES:
        xh, h, da = _geom(light)
        A.airlight(xh, h, da, ell, kt, 0.8 * kt, 1.0, ISOTROPIC, 0.0, 1e-6, 1000, 0, 1, co, POINT_ROW, stats)
    assert stats[A.ST_SERIES] > 0 and stats[A.ST_STABLE] > 0 and stats[A.ST_NEARLINE] == 2
    assert A.summarize_stats(stats)["mean_iterations_per_series_evaluation"] > 1


def test_taylor_coefficients_vs_mpmath():
    for code, g in [(RAYLEIGH, 0.0), (HG, 0.5), (HG, -0.4), (HG, 0.8)]:
        c = A.taylor_coeffs(code, g, 9)
        with mp.workdps(40):
            f = lambda v: _phase_mp(code, mp.mpf(g), (1 - v * v) / (1 + v * v))
            ref = mp.taylor(f, 0, 8)
        for n in range(9):
            assert c[n] == pytest.approx(float(ref[n]), rel=1e-12, abs=1e-14 * abs(float(ref[0])))
    c = A.taylor_coeffs(RAYLEIGH, 0.0, 9) * 8 * math.pi / 3
    assert np.allclose(c, [1, 0, -2, 0, 4, 0, -6, 0, 8])


@pytest.mark.parametrize("code,g,N", [(RAYLEIGH, 0.0, 3), (RAYLEIGH, 0.0, 6), (HG, 0.5, 6)])
def test_taylor_mode_equals_its_polynomial_phase(code, g, N):
    """PP-19 is exact for the truncated polynomial phase sum c_n v^n (well-conditioned H)."""
    c = A.taylor_coeffs(code, g, N)
    light, ell, kt = (2.0, 1.0, 0.0), 4.0, 0.5
    xh, h, da = _geom(light)

    def poly_phase(s, d):
        v = (d + s) / h if s > 0 else h / (d - s)
        return sum(float(cn) * v ** n for n, cn in enumerate(c))

    ref = _oracle(xh, h, ell, kt, 0.4, code, g, phase=poly_phase)
    stats = A.new_stats()
    val = A.airlight(xh, h, da, ell, kt, 0.4, 1.0, code, g, 1e-10, 1000, A.ANISO_TAYLOR, N, c, POINT_ROW, stats)
    assert val == pytest.approx(ref, rel=1e-8)
    assert stats[A.ST_TAYLOR_OUT] == 1  # v_b > R: the segment passes the light's foot point


@settings(max_examples=200, deadline=None)
@given(xh=st.floats(-50, 50), h=st.floats(1e-6, 20), ell=st.one_of(st.just(math.inf), st.floats(1e-3, 100)),
       kt=st.floats(0, 5), alb=st.floats(0, 1), code=st.sampled_from([0, 1, 2]), g=st.floats(-0.9, 0.9),
       mode=st.sampled_from([0, 1]), prec=st.sampled_from([1e-3, 1e-6]))
def test_random_inputs_finite_nonnegative(xh, h, ell, kt, alb, code, g, mode, prec):
    da = math.hypot(xh, h)
    co = A.make_coeffs(code, g, A.ANISO_EXACT, 3, prec)
    stats = A.new_stats()
    val = A.airlight(xh, h, da, ell, kt, alb * kt, 1.0, code, g, prec, 200, A.ANISO_EXACT, 3, co, POINT_ROW, stats)
    assert math.isfinite(val) and val >= 0.0
    iso = A.airlight(xh, h, da, ell, kt, alb * kt, 1.0, 0, 0.0, prec, 200, 0, 1, co, POINT_ROW, stats)
    assert math.isfinite(iso) and iso >= 0.0


def test_block_for_picks_the_shortest_block_that_holds_the_piece():
    """HG's ladder of fitted blocks (`exact_coeffs`): a piece v1 < v < v2 at H gets the shortest block
    whose range of v holds it and whose recurrence limit H_max admits H, the full one where none
    does; the ranges are those of FAR_ANGLES."""
    rng = np.random.default_rng(14)
    for g, precision in ((0.5, 1e-6), (0.9, 1e-6), (0.95, 1e-6), (-0.9, 1e-6), (0.9, 1e-9)):
        co = A.exact_coeffs(HG, g, precision)
        blocks = A.coefficient_blocks(co)
        assert len(blocks) >= 3 and blocks[0][A.B_VLO] == 0.0 and blocks[0][A.B_VHI] == math.inf
        ranges = {A.fitted_range(g, angle)[2:] for angle in A.FAR_ANGLES}
        assert all((b[A.B_VLO], b[A.B_VHI]) in ranges for b in blocks[1:])
        for _ in range(300):
            v1 = float(np.tan(0.5 * rng.uniform(0.0, math.pi)))
            v2 = math.inf if rng.random() < 0.2 else v1 + float(10 ** rng.uniform(-3, 1))
            H = float(10 ** rng.uniform(-3, 1))
            for at in (A.B_HMAX, A.B_HMAX_BAND):
                start, n, _ = A._block_at(co, v1, v2, H, at)
                chosen = co[start:start + n]
                holders = [b for b in blocks[1:] if b[A.B_VLO] <= v1 and v2 <= b[A.B_VHI] and H <= b[at]]
                assert len(chosen) == min(len(b) for b in holders + [blocks[0]])


def test_a_first_pass_counts_only_the_segments_it_evaluates():
    """`evaluate_segments` without the quadrature (the first pass of `evaluate_deferred`) leaves the
    segments that need it nan and counts nothing of them: its statistics are those of a pass with the
    quadrature over the other segments alone, and it returns how many it left."""
    from .test_compile import random_segments

    precision = A.working_precision(1e-8)
    coeffs = A.make_coeffs(HG, 0.9, A.ANISO_EXACT, 6, precision)
    xh, h, da, ell, rows = random_segments(400, 37)

    def run(sel, *extra):
        out, met, stats = np.empty(sel.sum()), np.empty(sel.sum(), dtype=np.bool_), A.new_stats()
        left = A.evaluate_segments(xh[sel], h[sel], da[sel], ell[sel], 2.0, 1.5, HG, 0.9, precision, 1000,
                                   A.ANISO_EXACT, 6, coeffs, rows[sel], out, met, stats, *extra)
        return out, stats, left

    every = np.ones(len(xh), dtype=np.bool_)
    first, stats, left = run(every, None, True, True)
    done = ~np.isnan(first)
    assert 0 < left == np.sum(~done)
    out, ref_stats, _ = run(done, True, True, True)
    assert np.array_equal(out, first[done]) and np.array_equal(stats, ref_stats)
