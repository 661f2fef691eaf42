"""Monte Carlo with sampling = cdf (issue 9): distances drawn by inverting the exact air-light CDF.

Checked against the reference quadrature, which shares no code with the closed form the CDF is built
from: the estimate equals the air-light with zero variance unoccluded (every phase function, random
geometries, and on the lit intervals of volumetric shadows); each drawn distance x_i satisfies
F(x_i) = u_i F(ell) to the Newton tolerance, and F(x_i) / F(ell) passes a Kolmogorov-Smirnov test
against uniform; with a shadow ray per sample the estimate is unbiased against the shadowed
quadrature and its variance is the visibility's alone, F^2 P (1 - P) / n."""
import math

import numpy as np
import pytest
from scipy import stats

import raytrace
from raytrace.methods.geometry import POINT_ROW
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH
from raytrace.methods import montecarlo as mc
from raytrace.methods import quadrature as q
from raytrace.rng import uniform

from .conftest import box_room, plate_room

PHASES = [(ISOTROPIC, 0.0), (RAYLEIGH, 0.0), (HG, 0.6), (HG, 0.9), (HG, -0.4)]


class _Medium:
    def __init__(self, code, g):
        self.phase, self.g = code, g


def quad(xh, h, ell, kt, ks, code, g, rtol=1e-12):
    st = np.zeros(3)
    val = q.airlight_one(xh, h, ell, kt, ks, code, g, POINT_ROW, rtol, q.N10, q.W10, q.N20, q.W20, st)
    assert st[q.CAPPED] == 0
    return val


def one(v):
    return np.array([v], float)


def cdf_estimate(xh, h, ell, kt, ks, code, g):
    out, var, st = np.zeros((1, 3)), np.zeros((1, 3)), np.zeros(mc.CDF_STATS)
    mc.airlight_segments_cdf(one(xh), one(h), one(math.hypot(xh, h)), one(ell), POINT_ROW[None], np.ones((1, 3)), np.full(3, kt),
                             np.full(3, ks), code, g, *mc.cdf_setup(_Medium(code, g)), out, var, st)
    return out[0], var[0]


def cdf_draws(xh, h, ell, kt, ks, code, g, n, key=5, seed=3):
    """n distances drawn on one segment along +z from the origin, their weights, and their u."""
    pos, w, st = np.zeros((1, n, 1, 3, 3)), np.zeros((1, n, 1, 3)), np.zeros(mc.CDF_STATS)
    mc.sample_points_cdf(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), one(xh), one(h), one(math.hypot(xh, h)),
                         one(ell), POINT_ROW[None], np.array([key], np.uint64), np.array([0]), np.uint64(seed), np.ones((1, 3)),
                         np.full(3, kt), np.full(3, ks), code, g, n, *mc.cdf_setup(_Medium(code, g)), pos, w, st)
    u = np.array([uniform(np.uint64(key), 2 * j, np.uint64(seed)) for j in range(n)])
    assert np.all(pos[0, :, 0, :, :2] == 0.0)  # on the segment
    return pos[0, :, 0, 0, 2], w[0, :, 0, 0], u, st


def random_geometries(count, seed):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        xh = rng.uniform(-6.0, 12.0)
        h = 10 ** rng.uniform(-3.0, 0.5)
        ell = math.inf if rng.random() < 0.25 else 10 ** rng.uniform(-2.0, 1.3)
        kt = 10 ** rng.uniform(-2.0, 0.5)
        out.append((xh, h, ell, kt))
    return out


@pytest.mark.parametrize("code,g", PHASES)
def test_estimate_is_the_air_light_with_zero_variance(code, g):
    worst = 0.0
    for xh, h, ell, kt in random_geometries(25, 100 + code + int(10 * g)):
        ks = 0.6 * kt
        ref = quad(xh, h, ell, kt, ks, code, g)
        est, var = cdf_estimate(xh, h, ell, kt, ks, code, g)
        worst = max(worst, abs(est[0] / ref - 1.0))
        assert np.all(var == 0.0)
        # the drawn samples' weights f/p are all F(ell): their mean is the same estimate
        _, w, _, _ = cdf_draws(xh, h, ell, kt, ks, code, g, 8)
        assert np.all(w == est[0])
    assert worst < 1e-8, worst


GEOMETRIES = [(2.0, 0.5, 6.0, 0.08), (2.0, 0.05, math.inf, 0.3), (3.0, 1.0, 4.0, 1.0), (-1.0, 0.3, 5.0, 0.5),
              (5.0, 0.01, 10.0, 0.2), (40.0, 0.02, 39.0, 0.1), (1.0, 3.0, 0.05, 2.0), (2.0, 0.2, 8.0, 3.0)]


@pytest.mark.parametrize("code,g", PHASES)
def test_distances_follow_the_cdf(code, g):
    """Per draw |F(x_i) / F(ell) - u_i| within the Newton tolerance (F by quadrature), and the
    F(x_i) / F(ell) of 300 draws uniform by Kolmogorov-Smirnov (fixed seed)."""
    for xh, h, ell, kt in GEOMETRIES:
        ks = 0.6 * kt
        x, _, u, st = cdf_draws(xh, h, ell, kt, ks, code, g, 300)
        total = quad(xh, h, ell, kt, ks, code, g, 1e-13)
        cdf = np.array([quad(xh, h, xi, kt, ks, code, g, 1e-13) for xi in x]) / total
        assert np.max(np.abs(cdf - u)) <= 2.0 * mc.NEWTON_TOL, (xh, h, ell, kt)
        assert stats.kstest(cdf, "uniform").pvalue > 1e-3
        assert st[mc.CS_NEWTON] + st[mc.CS_BISECT] < 12 * 300  # a few steps per draw





@pytest.mark.parametrize("phase", ["isotropic", "rayleigh", {"type": "hg", "g": 0.9}])
def test_render_is_exact_unoccluded_and_on_lit_intervals(phase):
    prep = plate_room(phase)
    for shadows in (False, True):
        ref = raytrace.render(prepared=prep, method="quadrature", rtol=1e-12, volumetric_shadows=shadows,
                              threads=1).array
        img = raytrace.render(prepared=prep, method="montecarlo", sampling="cdf", samples=4,
                              volumetric_shadows=shadows, threads=1)
        assert np.all(img.variance == 0.0)
        lit = ref > 1e-6 * ref.max()
        assert np.max(np.abs(img.array[lit] / ref[lit] - 1.0)) < 1e-8
        assert np.max(np.abs(img.array - ref)) < 1e-9 * ref.max()
        assert img.stats["cdf: closed-form evaluations"] > 0


@pytest.mark.parametrize("phase", ["isotropic", {"type": "hg", "g": 0.9}])
def test_shadow_rays_per_sample_are_unbiased_with_only_the_visibility_variance(phase):
    """Every weight is F(ell) V: a pixel's estimate is F(ell) k / n with k ~ Binomial(n, P), P the
    lit share of F(ell) (shadowed / unshadowed quadrature), so its variance is F^2 P (1 - P) / n.
    (A Z-test with the render's own variance does not suit: a pixel with n P << 1 often draws no lit
    sample at all and reports variance 0.)"""
    prep = plate_room(phase)
    ref = raytrace.render(prepared=prep, method="quadrature", rtol=1e-12, volumetric_shadows=True, threads=1).array
    unshadowed = raytrace.render(prepared=prep, method="quadrature", rtol=1e-12, volumetric_shadows=False,
                                 threads=1).array
    n = 64
    img = raytrace.render(prepared=prep, method="montecarlo", sampling="cdf", samples=n, volumetric_shadows=True,
                          shadow_test="samples", seed=4, threads=1)
    p = np.clip(ref / unshadowed, 0.0, 1.0)
    predicted = unshadowed ** 2 * p * (1.0 - p) / n
    # the whole image within 4 standard errors
    assert abs(np.sum(img.array - ref)) < 4.0 * math.sqrt(np.sum(predicted))
    # per pixel-channel: k = n estimate / F(ell) is an integer, and binomial (Sidak-corrected exact test)
    k = n * img.array / unshadowed
    assert np.max(np.abs(k - np.round(k))) < 1e-6
    k = np.round(k).astype(int)
    mixed = (p > 1e-9) & (p < 1.0 - 1e-9)
    per_test = 1.0 - (1.0 - 0.01) ** (1.0 / mixed.sum())
    pvalues = [stats.binomtest(int(a), n, float(b)).pvalue for a, b in zip(k[mixed], p[mixed])]
    assert min(pvalues) > per_test, min(pvalues)
    assert np.all(k[p <= 1e-9] == 0) and np.all(k[p >= 1.0 - 1e-9] == n)
    # the reported variance is the visibility's: on average the predicted one, 0 where fully lit or shadowed
    half = (p > 0.05) & (p < 0.95)
    assert half.sum() > 50
    ratio = np.mean(img.variance[half] / predicted[half])
    assert 0.85 < ratio < 1.15, ratio
    assert np.all(img.variance[~mixed] <= 1e-20 * ref.max() ** 2)


def test_sampling_choices_include_cdf_and_refuse_others():
    assert "cdf" in mc.METHOD.params["sampling"].choices
    with pytest.raises(raytrace.UserError, match="sampling"):
        raytrace.render(box_room(), method="montecarlo", sampling="inverse")
