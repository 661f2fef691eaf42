"""Every method integrates the fog whose light crosses an index-matched interior with its own rule
(inside_rows.through_airlight): raymarch with its midpoints, Monte Carlo with its samples, each point's
light attenuated by the interior on its straight path; quadrature (and slab_approx's fallback)
with the traced adaptive quadrature.

The twin, from the geometry alone: a camera in fog under a wide index-matched slab (y in [3, 3.5]),
a point light above the slab, a black wall 6 units ahead. The camera's central ray runs along -z at
height 1, so the light's path from every point of it crosses the slab, over the chord
0.5 d / 4 (d the distance to the light, 4 its height above the ray): the whole ray is one piece behind
the slab. Before, every method's image held the traced quadrature's value there (a raymarch at 8
steps was exact to 1e-10, Monte Carlo had no variance).
"""
import math

import numpy as np
import pytest
from scipy.integrate import quad

import raytrace

KS, KA = 0.1, 0.02
KT = KS + KA
KT_IN = np.array([0.6, 0.35, 0.2])  # the slab's sigma_t per channel
LIGHT = np.array([0.0, 5.0, -3.0])
I = 8.0
T_HIT = 6.0

SCENE = {
    "camera": {"position": [0.0, 1.0, 0.0], "look_at": [0.0, 1.0, -1.0], "width": 3, "height": 3, "spp": 1,
               "fov": 30.0},
    "shape": [{"primitive": "quad", "corners": [[-20, -20, -6], [20, -20, -6], [20, 20, -6], [-20, 20, -6]],
               "reflectance": 0.0},
              {"primitive": "box", "min": [-50.0, 3.0, -50.0], "max": [50.0, 3.5, 50.0],
               "interior": {"sigma_a": (KT_IN - 0.1).tolist(), "sigma_s": 0.1}}],
    "light": [{"position": LIGHT.tolist(), "intensity": I}],
    "medium": {"sigma_a": KA, "sigma_s": KS},
}


def integrand(x, c):
    """The attenuated air-light's integrand at distance x along the central ray, channel c."""
    p = np.array([0.0, 1.0, -x])
    d = float(np.linalg.norm(LIGHT - p))
    chord = 0.5 * d / 4.0
    return KS / (4.0 * math.pi) * I * math.exp(-KT * (x + d)) / d**2 * math.exp(-(KT_IN[c] - KT) * chord)


def render(method, **params):
    return raytrace.render(SCENE, method=method, threads=1, crop=(1, 1, 2, 2), **params)


def test_raymarch_marches_the_light_through_the_slab():
    """The render's pixel is the midpoint rule of 8 steps on the attenuated integrand (1e-10), not the
    exact integral (which it misses by far more at 8 steps), and the statistics name raymarch."""
    steps = 8
    twin = [T_HIT / steps * sum(integrand((i + 0.5) * T_HIT / steps, c) for i in range(steps)) for c in range(3)]
    exact = [quad(integrand, 0.0, T_HIT, args=(c,), epsabs=0.0, epsrel=1e-13)[0] for c in range(3)]
    img = render("raymarch", steps=steps)
    got = img.array[0, 0]
    assert np.all(np.abs(got - twin) <= 1e-10 * np.abs(twin)), (got, twin)
    assert np.all(np.abs(got - exact) > 1e-6 * np.abs(exact))  # the twin tells the rules apart
    assert img.stats["shadows: pieces through interiors (raymarch)"] == 1
    assert not any("(quadrature)" in k for k in img.stats)


def test_montecarlo_samples_the_light_through_the_slab():
    """Monte Carlo's pixel agrees with the exact integral within its own standard error (|z| < 5 per
    channel, with a variance that is not zero: its own samples, not a quadrature's value)."""
    exact = np.array([quad(integrand, 0.0, T_HIT, args=(c,), epsabs=0.0, epsrel=1e-13)[0] for c in range(3)])
    img = render("montecarlo", samples=256, seed=3)
    var = img.variance[0, 0]
    assert np.all(var > 0.0)
    z = (img.array[0, 0] - exact) / np.sqrt(var)
    assert np.all(np.abs(z) < 5.0), z
    assert img.stats["shadows: pieces through interiors (montecarlo)"] == 1


@pytest.mark.parametrize("method", ["quadrature", "slab_approx"])
def test_the_exact_methods_integrate_it_by_quadrature(method):
    """quadrature (its own rule) and slab_approx (whose outside rule, analytic's, has no closed form for
    light through an interior: its fallback, counted as quadrature) are exact
    to 1e-9, inside the bound of media/convex_chords.py's rule (finite: the slab is a convex box)."""
    exact = np.array([quad(integrand, 0.0, T_HIT, args=(c,), epsabs=0.0, epsrel=1e-13)[0] for c in range(3)])
    img = render(method)
    assert np.all(np.abs(img.array[0, 0] - exact) <= 1e-9 * exact)
    assert img.stats["shadows: pieces through interiors (quadrature)"] == 1
    assert np.all(np.isfinite(img.error_bound[0, 0]))
    assert np.all(np.abs(img.array[0, 0] - exact) <= img.error_bound[0, 0])
