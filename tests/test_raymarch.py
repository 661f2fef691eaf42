"""`raymarch` (METHODS.md §9.1) against the `quadrature` reference kernel: midpoint error O(h^2),
jittered marching unbiased over ray keys, the optical-depth cut-off for rays that hit nothing, and
finite values on edge inputs."""
import math

import numpy as np
import pytest

from raytrace.errors import UserError
from raytrace.lights import Light, Lights
from raytrace.media import Homogeneous as Medium
from raytrace.media.phase import HG, ISOTROPIC, RAYLEIGH
from raytrace.methods import quadrature as q, raymarch as rm
from raytrace.methods.geometry import POINT_ROW
from raytrace.segments import unshadowed_airlight


def ref(xh, h, ell, kt, ks, code=ISOTROPIC, g=0.0):
    return q.airlight_one(xh, h, ell, kt, ks, code, g, POINT_ROW, 1e-12, q.N10, q.W10, q.N20, q.W20, np.zeros(3))


def march(xh, h, ell, kt, ks, code=ISOTROPIC, g=0.0, steps=64, step=0.0, tau_max=20.0, xi=0.5):
    return rm.airlight_one(xh, h, ell, kt, ks, code, g, POINT_ROW, steps, step, tau_max, xi, np.zeros(3))


# H = 0.91, theta in [-0.99, 1.26] (the METHODS.md §8/§9.1 example)
H_EX, KT_EX = 0.91, 1.0
XH_EX = H_EX * math.tan(0.99)
ELL_EX = XH_EX + H_EX * math.tan(1.26)


@pytest.mark.parametrize("code,g", [(ISOTROPIC, 0.0), (RAYLEIGH, 0.0), (HG, 0.6)])
def test_midpoint_error_falls_as_h_squared(code, g):
    exact = ref(XH_EX, H_EX, ELL_EX, KT_EX, 0.8, code, g)
    ms = np.array([8, 16, 32, 64, 128, 256])
    err = np.array([abs(march(XH_EX, H_EX, ELL_EX, KT_EX, 0.8, code, g, steps=m) - exact) for m in ms])
    slope = np.polyfit(np.log(ELL_EX / ms), np.log(err), 1)[0]
    assert slope == pytest.approx(2.0, abs=0.2), (slope, err)
    if code == ISOTROPIC:  # METHODS.md §9.1: relative 3e-3, 2e-4, 1e-5 at M = 8, 32, 128
        np.testing.assert_allclose(err[[0, 2, 4]] / exact, [3.2e-3, 1.9e-4, 1.2e-5], rtol=0.1)


def test_step_length_is_the_step_count_of_the_same_spacing():
    a = march(XH_EX, H_EX, ELL_EX, KT_EX, 0.8, steps=50)
    b = march(XH_EX, H_EX, ELL_EX, KT_EX, 0.8, steps=7, step=ELL_EX / 49.5)  # ceil -> 50 cells
    assert a == b


def test_rays_that_hit_nothing_march_to_the_optical_depth_cutoff():
    kt, ks = 0.2, 0.14
    exact = ref(2.0, 1.0, math.inf, kt, ks)
    stats = np.zeros(3)
    got = rm.airlight_one(2.0, 1.0, math.inf, kt, ks, ISOTROPIC, 0.0, POINT_ROW, 0, 0.01, 20.0, 0.5, stats)
    assert stats[rm.SAMPLES] == 10000  # end = tau_max / kt = 100
    assert got == pytest.approx(exact, rel=1e-5)
    # a short cut-off loses the tail beyond it: tau_max = 1 stops at x = 5
    short = march(2.0, 1.0, math.inf, kt, ks, steps=4096, tau_max=1.0)
    assert short == pytest.approx(ref(2.0, 1.0, 5.0, kt, ks), rel=1e-6)


def _march_rays(n, ell, medium, lights, params, seed=0):
    o = np.zeros((n, 3))
    d = np.tile([1.0, 0.0, 0.0], (n, 1))
    return unshadowed_airlight(rm.METHOD, medium, lights, params, o, d, np.full(n, ell), np.arange(n, dtype=np.uint64),
                               seed)[:2]


def test_jittered_marching_is_unbiased_over_keys():
    xh, h, ell, kt, ks, steps, n = 2.1, 0.3, 5.0, 0.5, 0.4, 4, 20000  # light close to the ray: a peaky integrand
    medium = Medium(np.full(3, kt - ks), np.full(3, ks), ISOTROPIC)
    lights = Lights.of([Light(np.array([xh, h, 0.0]), np.ones(3))])
    params = {"steps": steps, "step": 0.0, "jitter": 1, "tau_max": 20.0}
    vals, stats = _march_rays(n, ell, medium, lights, params)
    vals = vals[:, 0]
    exact = ref(xh, h, ell, kt, ks)
    se = vals.std(ddof=1) / math.sqrt(n)
    assert abs(vals.mean() - exact) < 4 * se, (vals.mean(), exact, se)
    midpoint = march(xh, h, ell, kt, ks, steps=steps)
    assert abs(midpoint - exact) > 20 * se  # the midpoint rule is biased at 4 steps; jitter is not
    again, _ = _march_rays(n, ell, medium, lights, params)
    assert np.array_equal(again[:, 0], vals)  # deterministic in (key, seed)
    other, _ = _march_rays(n, ell, medium, lights, params, seed=1)
    assert not np.array_equal(other[:, 0], vals)
    assert stats[rm.EVALS] == n  # equal channels share one march


@pytest.mark.parametrize("xh,h,ell,kt", [
    (3.0, 1e-300, 6.0, 0.1),        # ray through the light
    (3.0, 1e-12, 6.0, 0.1),
    (2.0, 1.0, math.inf, 0.2),      # hits nothing
    (-1e4, 1.0, math.inf, 0.5),     # light far behind the camera
    (-3.0, 0.5, 4.0, 0.3),          # light behind the camera
    (1e6, 1.0, 10.0, 2.0),          # light far ahead
])
@pytest.mark.parametrize("code,g", [(ISOTROPIC, 0.0), (RAYLEIGH, 0.0), (HG, 0.9)])
def test_edge_inputs_are_finite(xh, h, ell, kt, code, g):
    for xi in (0.0, 0.5, 0.999):
        v = march(xh, h, ell, kt, 0.7 * kt, code, g, xi=xi)
        assert math.isfinite(v) and v >= 0.0
    assert march(xh, h, ell, 0.0, 0.0) == 0.0  # vacuum (kt = 0 implies ks = 0)
    assert march(xh, h, ell, kt, 0.0) == 0.0


def test_bad_parameters_are_rejected():
    from raytrace.methods import resolve_params
    ok = resolve_params(rm.METHOD, {}, "t")
    assert ok == {"steps": 64, "step": 0.0, "jitter": False, "tau_max": 20.0,
                  "shadow_test": "intervals", "transmittance": "closed"}
    for bad in ({"steps": 0}, {"step": -1.0}, {"tau_max": 0.0}, {"tau_max": math.inf}, {"jitter": 2}):
        with pytest.raises(UserError):
            resolve_params(rm.METHOD, bad, "t")
    assert resolve_params(rm.METHOD, {"jitter": "true"}, "t")["jitter"] is True