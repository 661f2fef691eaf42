"""`lecocq` (METHODS.md §8): Taylor coefficients of the whole angular integrand against mpmath,
accuracy near the light's foot point, and the raw artefacts PP09 reports when looking away from
the light (negative estimates, large over-evaluations), all against the `quadrature` reference."""
import math

import mpmath as mp
import numpy as np
import pytest

from raytrace.errors import UserError
from raytrace.lights import Light, Lights
from raytrace.media import Homogeneous as Medium
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH
from raytrace.methods import lecocq as lc, quadrature as q
from raytrace.methods.geometry import POINT_ROW
from raytrace.segments import unshadowed_airlight


def ref(xh, h, ell, kt, ks, code=ISOTROPIC, g=0.0):
    return q.airlight_one(xh, h, ell, kt, ks, code, g, POINT_ROW, 1e-12, q.N10, q.W10, q.N20, q.W20, np.zeros(3))


def lec(xh, h, ell, kt, ks, code=ISOTROPIC, g=0.0, terms=0, stats=None):
    stats = np.zeros(3) if stats is None else stats
    return lc.airlight_one(xh, h, ell, kt, ks, lc._TSEC, lc.phase_series(code, g),
                           lc.effective_terms(code, terms), np.zeros(2 * lc.MAX_TERMS), stats)


def from_theta(ta, tb, h):
    """(x_h, ell) of the segment [0, ell] whose angles at the light are [ta, tb]."""
    xh = -h * math.tan(ta)
    return xh, xh + h * math.tan(tb)


def mp_phase(code, g, mu):
    if code == ISOTROPIC:
        return 1 / (4 * mp.pi)
    if code == RAYLEIGH:
        return 3 / (16 * mp.pi) * (1 + mu**2)
    return (1 - g * g) / (4 * mp.pi * (1 + g * g - 2 * g * mu) ** mp.mpf(1.5))


def test_tan_plus_sec_series_are_the_zigzag_numbers():
    fact = np.array([math.factorial(k) for k in range(12)], float)
    np.testing.assert_array_equal(np.rint(lc.tan_sec_series(12) * fact),
                                  [1, 1, 1, 2, 5, 16, 61, 272, 1385, 7936, 50521, 353792])


def test_isotropic_coefficients_match_the_closed_forms():
    H = 0.7
    c = lc.integrand_coeffs(H, lc._TSEC, lc.phase_series(ISOTROPIC, 0.0), 5) * 4 * math.pi
    np.testing.assert_allclose(c, [1, -H, (H * H - H) / 2, -H * (H - 1) * (H - 2) / 6,
                                   (H**4 - 6 * H**3 + 11 * H**2 - 5 * H) / 24], rtol=1e-13)


@pytest.mark.parametrize("code,g", [(ISOTROPIC, 0.0), (RAYLEIGH, 0.0), (HG, 0.6), (HG, -0.4), (HG, 0.9)])
@pytest.mark.parametrize("H", [0.0, 0.3, 2.5])
def test_taylor_coefficients_match_mpmath(code, g, H):
    mp.mp.dps = 30
    n = 10

    def f(t):  # exp(-H (tan + sec - 1)) Phi_c(-sin): the integrand over exp(-H)
        return mp.exp(-H * (mp.tan(t) + mp.sec(t) - 1)) * mp_phase(code, g, -mp.sin(t))

    want = np.array([float(c) for c in mp.taylor(f, 0, n - 1)])
    got = lc.integrand_coeffs(H, lc._TSEC, lc.phase_series(code, g, lc.MAX_TERMS), n)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-13 * np.abs(want).max())


def test_accurate_when_the_segment_straddles_the_foot_point():
    # METHODS.md §8: 1.5 % at H = 0.91, theta in [-0.99, 1.26] (5 terms, isotropic)
    h = 0.91
    xh, ell = from_theta(-0.99, 1.26, h)
    rel = lec(xh, h, ell, 1.0, 1.0) / ref(xh, h, ell, 1.0, 1.0) - 1
    assert abs(rel) < 0.02
    # short segment around the foot point, small H: the truncation error is O(theta^5 H)
    h = 0.1
    xh, ell = from_theta(-0.3, 0.3, h)
    for code, g, tol in [(ISOTROPIC, 0.0, 1e-5), (RAYLEIGH, 0.0, 5e-3), (HG, 0.3, 2e-2)]:
        rel = lec(xh, h, ell, 1.0, 0.5, code, g) / ref(xh, h, ell, 1.0, 0.5, code, g) - 1
        assert abs(rel) < tol, (code, rel)
    # more terms converge on a segment inside the radius of convergence (|theta| < pi/2)
    errs = [abs(lec(xh, h, ell, 1.0, 0.5, terms=t) / ref(xh, h, ell, 1.0, 0.5) - 1) for t in (1, 3, 5, 7)]
    assert errs == sorted(errs, reverse=True) and errs[-1] < 1e-7


def test_looking_away_from_the_light_gives_negative_and_over_estimates():
    """Light behind the camera (theta_a > 0): the raw polynomial is no longer the integrand."""
    stats = np.zeros(3)
    # negative: light 1 behind, H = 1
    got, want = lec(-1.0, 1.0, 5.0, 1.0, 1.0, stats=stats), ref(-1.0, 1.0, 5.0, 1.0, 1.0)
    assert got < 0.0 < want and got < -0.3 * want, (got, want)
    assert stats[lc.NEGATIVE] == 1
    # over-evaluation by orders of magnitude: light 2 behind, H = 2
    got, want = lec(-2.0, 1.0, 5.0, 2.0, 2.0), ref(-2.0, 1.0, 5.0, 2.0, 2.0)
    assert got > 100 * want > 0, (got, want)
    # over-evaluation > 2x with Rayleigh (3 terms), light 3 behind, H = 1.2
    got, want = lec(-3.0, 0.4, 4.0, 3.0, 1.0, RAYLEIGH), ref(-3.0, 0.4, 4.0, 3.0, 1.0, RAYLEIGH)
    assert abs(got) > 2 * want, (got, want)


def test_defaults_and_driver():
    assert lc.effective_terms(ISOTROPIC, 0) == 5 and lc.effective_terms(RAYLEIGH, None) == 3
    assert lc.effective_terms(HG, 4) == 4
    medium = Medium(np.array([0.0, 0.0, 0.2]), np.array([1.0, 1.0, 0.3]), RAYLEIGH)
    h = 0.5
    xh, ell = from_theta(-0.4, 0.5, h)
    lights = Lights.of([Light(np.array([xh, h, 0.0]), np.array([2.0, 2.0, 3.0]))])
    out, stats, _ = unshadowed_airlight(lc.METHOD, medium, lights, {"terms": 0}, np.zeros((2, 3)),
                                        np.tile([1.0, 0.0, 0.0], (2, 1)), np.array([ell, ell]),
                                        np.arange(2, dtype=np.uint64))
    want = [2 * lec(xh, h, ell, 1.0, 1.0, RAYLEIGH), 3 * lec(xh, h, ell, 0.5, 0.3, RAYLEIGH)]
    np.testing.assert_allclose(out[0], [want[0], want[0], want[1]], rtol=1e-14)
    assert stats[lc.EVALS] == 4  # two rays, two distinct channels
    from raytrace.methods import resolve_params
    assert resolve_params(lc.METHOD, {"terms": 0}, "t")["terms"] == 0
    with pytest.raises(UserError):
        resolve_params(lc.METHOD, {"terms": 99}, "t")


@pytest.mark.parametrize("xh,h,ell,kt", [
    (3.0, 1e-300, 6.0, 0.1),        # ray through the light
    (2.0, 1.0, math.inf, 0.2),      # hits nothing
    (-3.0, 0.5, 4.0, 0.3),          # light behind the camera
    (-300.0, 2.0, math.inf, 0.01),
    (1e6, 1.0, 10.0, 2.0),          # light far ahead: underflows to 0
    (2.0, 1.0, 5.0, 0.0),           # vacuum with ks = 0
])
@pytest.mark.parametrize("code,g", [(ISOTROPIC, 0.0), (RAYLEIGH, 0.0), (HG, 0.9)])
def test_edge_inputs_are_finite(xh, h, ell, kt, code, g):
    assert math.isfinite(lec(xh, h, ell, kt, 0.7 * kt, code, g))


def test_far_behind_saturates_instead_of_overflowing():
    stats = np.zeros(3)
    v = lec(-1e4, 1.0, math.inf, 0.5, 0.4, stats=stats)  # exp(+5000) prefactor
    assert math.isfinite(v) and abs(v) == lc.SATURATE and stats[lc.SATURATED] == 1
