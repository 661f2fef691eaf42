"""Inside an index-matched box of medium, a lamp's light crosses another, denser index-matched box on
its way (shadows/through_others.py): the light is attenuated by that box's extinction over its chord.

The twin uses the geometry alone: the light's straight path from each point of the camera's segment,
its length inside the first box and its chord through the second by slab tests, the integrand
ks Phi(mu) I / d^2 exp(-kt_A (x + k_A) - kt_B c_B - kt_out (d - k_A - c_B)), and scipy `quad_vec`
between the points where the faces the path leaves the first box by, or enters and leaves the second
by, change (bisected on that indicator), and, for a spot, where the path crosses its cone. Without the attenuation (as before, and with volumetric
shadows off) the pixels are far off. The same under the sun (no outside medium), the dense box
between the sun and part of the fog box: ks Phi(mu) E exp(-kt (x + k_A) - kt_B c_B), its breaks
also where the sun's path meets the boxes' edges. quadrature's bound holds under both, and analytic
hands these segments to it.
"""
import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import oracle
from .conftest import to_toml
from .test_bounded_media import box_entry, slab
from .test_refracted_point_light import switches

LO, HI = -np.ones(3), np.ones(3)
LO_B, HI_B = np.array([-0.6, 1.6, -1.4]), np.array([1.4, 2.4, 0.3])
INNER = {"sigma_a": [0.2, 0.1, 0.05], "sigma_s": [0.5, 0.6, 0.7], "phase": {"type": "hg", "g": 0.3}}
DENSE = {"sigma_a": [1.5, 1.0, 0.5], "sigma_s": [0.0, 0.0, 0.0]}
CAMERA = {"position": [0.4, 0.1, 5.0], "look_at": [0.0, 0.0, 0.0], "fov": 18.0, "width": 7, "height": 6, "spp": 1}
SCENE = {"name": "boxes_in_line", "camera": CAMERA,
         "shape": [{"primitive": "box", "min": LO.tolist(), "max": HI.tolist(), "interior": INNER},
                   {"primitive": "box", "min": LO_B.tolist(), "max": HI_B.tolist(), "interior": DENSE}],
         "light": [{"position": [0.3, 4.0, 0.2], "intensity": [6.0, 5.0, 4.0]}],
         "medium": {"sigma_a": 0.02, "sigma_s": 0.0}}


def path(X, L):
    """(d, u, k_A, c_B, faces): the straight path from X in the first box to the light."""
    d = float(np.linalg.norm(L - X))
    u = (L - X) / d
    k_a, n_a = oracle.box_exit(X, u, LO, HI)
    hit = slab(X, u, LO_B, HI_B)
    c_b, faces = 0.0, (tuple(n_a),)
    if hit is not None:
        t_in, t_out, n_b = hit
        c_b = max(0.0, min(t_out, d) - max(t_in, 0.0))
        if c_b > 0.0:
            faces += (tuple(n_b), t_out < d)
    return d, u, k_a, c_b, faces


def pixel(i, j, f, indicator, extra=lambda p, d, ell: []):
    """(t0, the integral of f(x, p, d) over pixel (i, j)'s segment in the first box): scipy `quad_vec`
    between the points where indicator(X) changes along it (bisected) and extra(p, d, ell); None where
    the ray misses the box. epsabs 1e-300: quad_vec's test of convergence is strict, so a piece the spot
    leaves dark (its integral 0) would be split to the limit; lit pieces are held to epsrel alone."""
    o, d = oracle.camera_ray(CAMERA, i, j)
    t0, n_in = box_entry(o, d, LO, HI)
    if n_in is None:
        return None
    p = o + t0 * d
    ell, _ = oracle.box_exit(p, d, LO, HI)
    cuts = switches(p, d, ell, lambda x: str(indicator(p + x * d)), samples=400) + extra(p, d, ell)
    edges = [0.0, *sorted(cuts), ell]
    return t0, sum(integrate.quad_vec(lambda x: f(x, p, d), a, b, epsabs=1e-300, epsrel=1e-12, norm="max",
                                      limit=400)[0] for a, b in zip(edges, edges[1:]) if b > a)


def twin_pixel(i, j, light=SCENE["light"][0]):
    """The lamp's (or a spot's: its falloff toward X, its cone crossings solved by oracle.cone_crossings)
    pixel (i, j)."""
    L = np.array(light["position"])
    inten = np.array(light["intensity"])
    spot, curve = oracle.spot_of(light), light.get("falloff", "smoothstep")
    ks = np.array(INNER["sigma_s"])
    kt = np.array(INNER["sigma_a"]) + ks
    kt_b = np.array(DENSE["sigma_a"])
    kt_out = SCENE["medium"]["sigma_a"]

    def f(x, p, d):
        dist, u, k_a, c_b, _ = path(p + x * d, L)
        mu = float(u @ d)
        return (inten * ks * oracle.phase("hg", INNER["phase"]["g"], mu) / dist**2 * oracle.emission(spot, -u, curve)
                * np.exp(-kt * (x + k_a) - kt_b * c_b - kt_out * (dist - k_a - c_b)))

    hit = pixel(i, j, f, lambda X: path(X, L)[4], lambda p, d, ell: oracle.cone_crossings(p, d, ell, L, spot))
    return np.zeros(3) if hit is None else math.exp(-kt_out * hit[0]) * hit[1]


@pytest.fixture(scope="module")
def twin():
    return np.array([[twin_pixel(i, j) for i in range(CAMERA["width"])] for j in range(CAMERA["height"])])


def image(method, params=None, seed=0, shadows=True, scene=SCENE):
    prep = prepare(scene_from_text(to_toml(scene), scene["name"]))
    return render(prep, method, params or {}, RenderOptions(threads=1, seed=seed, volumetric_shadows=shadows))


def test_the_dense_box_stands_in_the_light(twin):
    """Not vacuous: on most pixels part of the segment's light crosses the dense box, and ignoring it
    (volumetric shadows off: the other interior's attenuation is not applied) is far off."""
    lit = twin[..., 1] > 0
    assert np.count_nonzero(lit) == CAMERA["width"] * CAMERA["height"]
    bare = image("quadrature", {"rtol": 1e-10}, shadows=False).image
    off = np.abs(bare - twin) / twin
    assert np.count_nonzero(off > 0.05) >= 20, np.sort(off.ravel())[-5:]


def test_quadrature_matches_the_twin(twin):
    res = image("quadrature", {"rtol": 1e-10})
    rel = np.abs(res.image - twin) / twin
    assert np.max(rel) < 1e-8, np.max(rel)
    assert res.stats["inside: integrals not converged"] == 0


@pytest.mark.parametrize("rtol", [1e-10, 1e-6])
def test_quadrature_bounds_the_lamplit_pixels(twin, rtol):
    """quadrature's error bound under the lamp through the dense box (its rule, A's path's rounding
    and the dense box's chord's toward the lamp, with the planes' errors) holds against the twin on
    every pixel and is not vacuous: its median at most 10 rtol of the value."""
    res = image("quadrature", {"rtol": rtol})
    assert np.all(np.isfinite(res.error_bound))
    err = np.abs(res.image - twin)
    assert np.all(err <= res.error_bound + 1e-12 * twin), np.max(err / res.error_bound)
    assert np.median(res.error_bound / twin) <= 10.0 * rtol, np.median(res.error_bound / twin)


# A spot at the lamp's place aimed into the fog box, its cone cutting the box and the dense box.
SPOT = {"type": "spot", "position": [0.3, 4.0, 0.2], "look_at": [0.1, 0.0, 0.0], "cone_angle": 12.0,
        "falloff_start": 6.0, "intensity": [6.0, 5.0, 4.0]}
SPOT_SCENE = {**SCENE, "name": "spot_through_the_dense_box", "light": [SPOT]}


@pytest.fixture(scope="module")
def spot_twin():
    return np.array([[twin_pixel(i, j, SPOT) for i in range(CAMERA["width"])] for j in range(CAMERA["height"])])


@pytest.mark.parametrize("rtol", [1e-10, 1e-6])
def test_the_spot_through_the_dense_box_is_bounded(spot_twin, rtol):
    """The spot's cone cuts the fog box (some pixels dark, others lit in part) and its light crosses
    the dense box: quadrature matches the twin, its bound finite, never exceeded, its median at most
    10 rtol of the value."""
    lit = spot_twin[..., 1] > 0
    assert 0 < np.count_nonzero(lit) < lit.size
    res = image("quadrature", {"rtol": rtol}, scene=SPOT_SCENE)
    err = np.abs(res.image - spot_twin)
    assert np.all(err <= 10.0 * rtol * spot_twin + 1e-14), np.max(err[lit] / spot_twin[lit])
    assert np.all(np.isfinite(res.error_bound)) and np.all(err <= res.error_bound + 1e-12 * spot_twin)
    assert np.median(res.error_bound[lit] / spot_twin[lit]) <= 10.0 * rtol


@pytest.mark.parametrize("scene, reference", [("lamp", "twin"), ("sun", "sun_twin")])
def test_raymarch_and_montecarlo_take_the_attenuation(scene, reference, request):
    """Under the lamp and under the sun: raymarch converges to the twin, montecarlo passes a z-test."""
    scene, twin = SUN_SCENE if scene == "sun" else SCENE, request.getfixturevalue(reference)
    errs = [np.max(np.abs(image("raymarch", {"steps": n}, scene=scene).image - twin) / twin) for n in (64, 256)]
    assert errs[1] < 2e-3 and errs[1] < errs[0] / 3.0, errs
    res = image("montecarlo", {"samples": 64}, seed=4, scene=scene)
    z2 = np.mean((res.image - twin) ** 2 / res.variance)
    assert 0.3 < z2 < 3.5, z2


# Under the sun: the same fog box, no outside medium, the dense box between the sun and part of it.
SUN = {"type": "directional", "direction": [0.3, -1.0, 0.2], "irradiance": [2.0, 1.5, 1.0]}
SUN_SCENE = {**{k: v for k, v in SCENE.items() if k != "medium"}, "name": "box_under_the_sun", "light": [SUN]}


def sun_path(X):
    """(u, k_A, c_B, faces): the path from X in the first box toward the sun (s >= 0)."""
    u = -np.array(SUN["direction"]) / np.linalg.norm(SUN["direction"])
    k_a, n_a = oracle.box_exit(X, u, LO, HI)
    hit = slab(X, u, LO_B, HI_B)
    c_b, faces = 0.0, (tuple(n_a),)
    if hit is not None and hit[1] > 0.0:
        c_b = hit[1] - max(hit[0], 0.0)
        leave = [max((LO_B[a] - X[a]) / u[a], (HI_B[a] - X[a]) / u[a]) for a in range(3)]
        faces += (tuple(hit[2]), int(np.argmin(leave)))  # the faces it enters and leaves by
    return u, k_a, c_b, faces


def edge_crossings(p, d, u, lo, hi, ell):
    """The x in (0, ell) where the sun's path from p + x d meets an edge of the box [lo, hi]: the
    edge's point in the plane through the segment along u, decomposed as p + x d + s u (s > 0)."""
    n = np.cross(d, u)
    out = []
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        for vb in (lo[b], hi[b]):
            for vc in (lo[c], hi[c]):
                v = np.zeros(3)
                v[a], v[b], v[c] = lo[a], vb, vc
                e = np.eye(3)[a] * (hi[a] - lo[a])
                if e @ n == 0.0:
                    continue
                t = (p - v) @ n / (e @ n)
                if 0.0 <= t <= 1.0:
                    x, s_ = np.linalg.lstsq(np.stack([d, u], axis=1), v + t * e - p, rcond=None)[0]
                    if 0.0 < x < ell and s_ > 0.0:
                        out.append(float(x))
    return out


def sun_twin_pixel(i, j):
    """ks Phi(mu) E exp(-kt (x + k_A) - kt_B c_B) over the segment in the first box, scipy `quad_vec`
    between the points where the faces the sun's path leaves A by or crosses B by change (bisected
    on that indicator) and where the path meets an edge of either box (two such changes closer than
    the indicator's grid)."""
    e = np.array(SUN["irradiance"])
    ks = np.array(INNER["sigma_s"])
    kt = np.array(INNER["sigma_a"]) + ks
    kt_b = np.array(DENSE["sigma_a"])

    def f(x, p, d):
        u, k_a, c_b, _ = sun_path(p + x * d)
        return e * ks * oracle.phase("hg", INNER["phase"]["g"], float(u @ d)) * np.exp(-kt * (x + k_a) - kt_b * c_b)

    def edges(p, d, ell):
        u = sun_path(p)[0]
        return edge_crossings(p, d, u, LO, HI, ell) + edge_crossings(p, d, u, LO_B, HI_B, ell)

    hit = pixel(i, j, f, lambda X: sun_path(X)[3], edges)
    return np.zeros(3) if hit is None else hit[1]


@pytest.fixture(scope="module")
def sun_twin():
    return np.array([[sun_twin_pixel(i, j) for i in range(CAMERA["width"])] for j in range(CAMERA["height"])])


def sun_image(method, params=None, seed=0, shadows=True):
    return image(method, params, seed, shadows, SUN_SCENE)


def test_the_dense_box_shades_part_of_the_sunlit_box(sun_twin):
    """Not vacuous: the dense box shades some pixels' segments wholly or in part and leaves others
    lit; without its attenuation (volumetric shadows off, as with them before) the shaded pixels
    are far off."""
    assert np.all(sun_twin[..., 1] > 0)
    bare = sun_image("quadrature", {"rtol": 1e-10}, shadows=False).image
    off = np.abs(bare - sun_twin) / sun_twin
    assert np.count_nonzero(off > 0.05) >= 10 and np.count_nonzero(off < 1e-6) >= 1, np.sort(off.ravel())


def test_quadrature_under_the_sun_matches_the_twin(sun_twin):
    res = sun_image("quadrature", {"rtol": 1e-10})
    rel = np.abs(res.image - sun_twin) / sun_twin
    assert np.max(rel) < 1e-9, np.max(rel)
    assert res.stats["inside: integrals not converged"] == 0


def test_analytic_hands_the_sunlit_segments_to_quadrature(sun_twin):
    """analytic has no closed form with the other box's chord: its segments go to the quadrature at
    the inside rtol, counted, and bounded."""
    res = sun_image("analytic")
    rel = np.abs(res.image - sun_twin) / sun_twin
    assert np.max(rel) < 1e-9, np.max(rel)
    assert res.stats["inside: segments handed to quadrature"] >= CAMERA["width"] * CAMERA["height"]
    assert np.all(np.isfinite(res.error_bound)) and np.all(np.abs(res.image - sun_twin) <= res.error_bound)


@pytest.mark.parametrize("rtol", [1e-10, 1e-6])
def test_quadrature_bounds_the_sunlit_pixels(sun_twin, rtol):
    """quadrature's error bound under the sun through the dense box (its rule, A's path's and the
    dense box's chord's rounding with their planes' errors) holds against the twin (to its own 1e-12)
    on every pixel and is not vacuous: its median at most 10 rtol of the value."""
    res = sun_image("quadrature", {"rtol": rtol})
    assert np.all(np.isfinite(res.error_bound))
    err = np.abs(res.image - sun_twin)
    assert np.all(err <= res.error_bound + 1e-12 * sun_twin), np.max(err / res.error_bound)
    assert np.median(res.error_bound / sun_twin) <= 10.0 * rtol, np.median(res.error_bound / sun_twin)
