"""Inside a convex refractive shape, a point light's refracted paths are attenuated by another,
index-matched interior on their outside leg, from the light to the refraction point on the face
(shadows/through_others.py `refracted_attenuated`): the water box of tests/test_refracted_point_light.py
under its lamp, with a dense absorbing box between the lamp and part of the water's top face.

Before this change the dense box was not applied to those legs: the image was that of the water box
alone, too bright wherever a leg crosses the dense box (`test_the_dense_box_shades_part_of_the_legs`).
quadrature's error bound there (the refracted paths' rounding, the breaks' location and the legs'
chords, docs/error_bounds.md) holds against the twin and is not vacuous at rtol 1e-10 and 1e-6.

The twin uses the geometry alone: for each face whose plane the lamp is outside of, Fermat's
refraction point R on that plane is the minimiser of the optical path |R - L| + eta |R - X| (a convex
function of R: the root of its gradient in the plane, scipy `root`), counted where R lies on the face;
the ray tube's irradiance and the Fresnel transmittance as tests/test_refracted_point_light.py; the
leg's chord through the dense box by a slab test, so the integrand is
    ks Phi(mu) T E exp(-kt (x + k) - kt_out o - (kt_B - kt_out) c_B),
integrated by scipy `quad_vec` between the points where R crosses its face's edges or the faces the
leg enters and leaves the dense box by change (each bisected on that indicator).
"""
import math

import numpy as np
import pytest
from scipy import integrate, optimize

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import oracle
from .conftest import to_toml
from .test_bounded_media import box_entry, fresnel_t, slab, snell
from .test_refracted_point_light import FACES, HI, LO, WATER, on_face, switches, tube

LO_B, HI_B = np.array([0.3, 1.45, -0.2]), np.array([1.0, 1.75, 0.4])
DENSE = {"sigma_a": [1.5, 1.0, 0.5], "sigma_s": [0.0, 0.0, 0.0]}
CAMERA = {**WATER["camera"], "width": 5, "height": 4}
SCENE = {**WATER, "name": "water_box_under_a_dense_box", "camera": CAMERA,
         "shape": WATER["shape"] + [{"primitive": "box", "min": LO_B.tolist(), "max": HI_B.tolist(),
                                     "interior": DENSE}]}
LAMP = np.array(WATER["light"][0]["position"], float)


def refraction_point(X, n, c, eta):
    """The minimiser R of |R - L| + eta |R - X| on the plane n·q = c (X below it, L above), from the
    gradient's root in two directions across n, started at the straight path's crossing."""
    u = np.cross(n, [0.3, 0.5, 0.7])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    base = X + (c - n @ X) / (n @ (LAMP - X)) * (LAMP - X)

    def grad(s):
        R = base + s[0] * u + s[1] * v
        g = (R - LAMP) / np.linalg.norm(R - LAMP) + eta * (R - X) / np.linalg.norm(R - X)
        return [g @ u, g @ v]

    sol = optimize.root(grad, [0.0, 0.0], method="hybr", options={"xtol": 1e-15})
    assert np.max(np.abs(grad(sol.x))) < 1e-12
    return base + sol.x[0] * u + sol.x[1] * v


def leg(R):
    """(chord, the faces it enters and leaves by) of the segment from R to the lamp in the dense box."""
    d = LAMP - R
    dist = np.linalg.norm(d)
    hit = slab(R, d / dist, LO_B, HI_B)
    if hit is None or hit[1] <= 0.0 or hit[0] >= dist:
        return 0.0, None
    leave = [max((LO_B[a] - R[a]) / d[a] * dist, (HI_B[a] - R[a]) / d[a] * dist) if d[a] else math.inf
             for a in range(3)]
    return min(hit[1], dist) - max(hit[0], 0.0), (tuple(hit[2]), int(np.argmin(leave)))


def twin_pixel(i, j, dense=True):
    inner = WATER["shape"][0]["interior"]
    eta, g = inner["ior"], inner["phase"]["g"]
    ks = np.array(inner["sigma_s"], float)
    kt = np.array(inner["sigma_a"], float) + ks
    kt_out = WATER["medium"]["sigma_a"] + WATER["medium"]["sigma_s"]
    dk = (np.array(DENSE["sigma_a"], float) - kt_out) if dense else np.zeros(3)
    inten = np.array(WATER["light"][0]["intensity"], float)
    o_cam, d = oracle.camera_ray(CAMERA, i, j)
    t0, n_in = box_entry(o_cam, d, LO, HI)
    if n_in is None:
        return np.zeros(3)
    p = o_cam + t0 * d
    w, ti, tt = snell(d, n_in, eta)
    ell = oracle.box_exit(p, w, LO, HI)[0]
    out = np.zeros(3)
    for n in FACES:
        if n @ LAMP <= 1.0:
            continue

        def f(x):
            X = p + x * w
            R = refraction_point(X, n, 1.0, eta)
            if not on_face(R, n):
                return np.zeros(3)
            o, k = np.linalg.norm(R - LAMP), np.linalg.norm(R - X)
            hl, z = n @ LAMP - 1.0, 1.0 - n @ X
            cos1, cos2 = hl / o, z / k
            foot_l, foot_x = LAMP - hl * n, X + z * n
            rho = np.linalg.norm(foot_l - foot_x)
            e = fresnel_t(math.acos(cos1), math.asin(math.sqrt(1.0 - cos1**2) / eta), eta) * tube(hl, z, cos1, cos2,
                                                                                                   rho, eta)
            mu = float((X - R) @ -w) / k
            return ks * oracle.phase("hg", g, mu) * e * inten * np.exp(-kt * (x + k) - kt_out * o - dk * leg(R)[0])

        cuts = switches(p, w, ell, lambda x: on_face(refraction_point(p + x * w, n, 1.0, eta), n), samples=120)
        if dense:
            cuts += switches(p, w, ell, lambda x: str(leg(refraction_point(p + x * w, n, 1.0, eta))[1]), samples=120)
        edges = [0.0, *sorted(cuts), ell]
        for a, b in zip(edges, edges[1:]):
            if b > a:
                out += integrate.quad_vec(f, a, b, epsabs=0.0, epsrel=1e-11, norm="max", limit=200)[0]
    return math.exp(-kt_out * t0) * fresnel_t(ti, tt, eta) / eta**2 * out


# pixels (i, j) compared: two whose legs cross the dense box, two whose legs do not (the twin's
# scipy root per evaluation is too slow for the whole image)
PIXELS = [(2, 2), (2, 1), (3, 1), (3, 2)]


def twin_image(dense=True):
    return np.array([twin_pixel(i, j, dense) for i, j in PIXELS])


def at_pixels(img):
    return np.array([img[j, i] for i, j in PIXELS])


@pytest.fixture(scope="module")
def twin():
    return twin_image()


def image(method, params=None, seed=0):
    prep = prepare(scene_from_text(to_toml(SCENE), SCENE["name"]))
    return render(prep, method, params or {}, RenderOptions(threads=1, seed=seed, volumetric_shadows=True))


def test_the_dense_box_shades_part_of_the_legs(twin):
    """Not vacuous: no camera ray crosses the dense box, and its shade changes many pixels by far more
    than the tolerance (the image without it, which the renderer gave before, is too bright there)."""
    for i in range(CAMERA["width"]):
        for j in range(CAMERA["height"]):
            o, d = oracle.camera_ray(CAMERA, i, j)
            hit = slab(o, d, LO_B, HI_B)
            assert hit is None or hit[1] < 0.0
    assert np.all(twin > 0)
    bare = twin_image(dense=False)
    off = (bare - twin) / twin
    assert np.all(off[:2, 0] > 0.05) and np.all(np.abs(off[2:]) < 1e-12), off


@pytest.mark.parametrize("rtol", [1e-10, 1e-6])
def test_quadrature_takes_the_dense_box(twin, rtol):
    """quadrature matches the twin, within its error bound (finite on every pixel: until this change
    it was infinite, the refracted paths' rounding and the legs' chords not analysed), whose median
    is at most 10 rtol of the value."""
    res = image("quadrature", {"rtol": rtol})
    rel = np.abs(at_pixels(res.image) - twin) / twin
    assert np.max(rel) < max(1e-8, 2.0 * rtol), np.max(rel)
    assert res.stats["inside: integrals not converged"] == 0
    assert np.all(np.isfinite(res.error_bound))
    bound = at_pixels(res.error_bound)
    assert np.all(np.abs(at_pixels(res.image) - twin) <= bound), np.max(np.abs(at_pixels(res.image) - twin) / bound)
    assert np.median(bound / twin) <= 10.0 * rtol, np.median(bound / twin)


def test_raymarch_and_montecarlo_take_the_dense_box(twin):
    """raymarch converges to the twin, montecarlo passes a z-test (their own rules, no bound)."""
    rel = {n: np.max(np.abs(at_pixels(image("raymarch", {"steps": n}).image) - twin) / twin) for n in (128, 512)}
    assert rel[512] < 5e-3 and rel[512] < rel[128] / 2.5, rel
    res = image("montecarlo", {"samples": 64}, seed=3)
    z2 = np.mean((at_pixels(res.image) - twin) ** 2 / at_pixels(res.variance))
    assert 0.3 < z2 < 3.5, z2
