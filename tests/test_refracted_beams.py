"""A directional light inside a convex refractive shape enters through every face it meets
(bounded.refracted_beams): a cube of water under a low sun, seen across two lit faces, against an
independent twin.

The twin (Snell and Fresnel by angles, tests/test_bounded_media.py) refracts the sun through each
face that faces it, follows each refracted beam back from every point of the camera's inside segment
to the cube's wall by the slab test, keeps it where that wall is the face it entered by, and
integrates with scipy `quad` between the points where a beam starts or stops reaching the segment
(bisected on its indicator). The entry-plane model of the slab note (eq. 5) is off by over 10 % on
these pixels, so the test tells the two apart.
"""
import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.options import RenderOptions
from raytrace.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import oracle
from .conftest import to_toml
from .test_bounded_media import box_entry, fresnel_t, snell

LO, HI = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
SUN = {"type": "directional", "direction": [1.0, -0.5, 0.3], "irradiance": 3.0}
SCENE = {"name": "cube_of_water",
         "camera": {"position": [-4.0, 3.0, 5.0], "look_at": [0.0, 0.0, 0.0], "fov": 26.0, "width": 12,
                    "height": 9, "spp": 1},
         "shape": [{"primitive": "box", "min": LO.tolist(), "max": HI.tolist(),
                    "interior": {"sigma_a": [0.4, 0.1, 0.05], "sigma_s": [0.3, 0.5, 0.8],
                                 "phase": {"type": "hg", "g": 0.5}, "ior": 1.33}}],
         "light": [SUN]}
FACES = [np.eye(3)[a] * s for a in range(3) for s in (-1.0, 1.0)]


def beams(eta, sun=SUN):
    """(outward normal, refracted direction, irradiance inside) for each face of a box the sun meets."""
    s = np.array(sun["direction"], float)
    s /= np.linalg.norm(s)
    out = []
    for n in FACES:
        if float(s @ n) < 0.0:
            t, ti, tt = snell(s, n, eta)
            out.append((n, t, sun["irradiance"] * fresnel_t(ti, tt, eta) * math.cos(ti) / math.cos(tt)))
    return out


def reaches(X, n, t, lo=LO, hi=HI):
    """Whether the beam refracted through face n (direction t) of the box [lo, hi] reaches X: its
    path back leaves there."""
    _, inward = oracle.box_exit(X, -t, lo, hi)
    return np.allclose(-inward, n)


def switches(p, w, ell, n, t, lo=LO, hi=HI, samples=400):
    """The x in (0, ell) where the beam starts or stops reaching p + x w, bisected to doubles."""
    xs = np.linspace(0.0, ell, samples + 1)
    on = [reaches(p + x * w, n, t, lo, hi) for x in xs]
    out = []
    for i in np.nonzero(np.array(on[:-1]) != np.array(on[1:]))[0]:
        a, b = xs[i], xs[i + 1]
        while b - a > 4e-16 * ell:
            m = 0.5 * (a + b)
            if reaches(p + m * w, n, t, lo, hi) == on[i]:
                a = m
            else:
                b = m
        out.append(0.5 * (a + b))
    return out


def twin_pixel(i, j):
    inner = SCENE["shape"][0]["interior"]
    eta, g = inner["ior"], inner["phase"]["g"]
    ks = np.array(inner["sigma_s"], float)
    kt = np.array(inner["sigma_a"], float) + ks
    o, d = oracle.camera_ray(SCENE["camera"], i, j)
    t0, n_in = box_entry(o, d, LO, HI)
    if n_in is None:
        return np.zeros(3)
    p = o + t0 * d
    w, ti, tt = snell(d, n_in, eta)
    ell, _ = oracle.box_exit(p, w, LO, HI)
    out = np.zeros(3)
    for n, t, e_in in beams(eta):
        phase = oracle.phase("hg", g, float(-(t @ w)))
        edges = [0.0, *switches(p, w, ell, n, t), ell]
        for a, b in zip(edges, edges[1:]):
            if not reaches(p + 0.5 * (a + b) * w, n, t):
                continue
            for c in range(3):
                def f(x):
                    X = p + x * w
                    k, _ = oracle.box_exit(X, -t, LO, HI)
                    return ks[c] * phase * e_in * math.exp(-kt[c] * (x + k))
                out[c] += integrate.quad(f, a, b, epsabs=0.0, epsrel=1e-12, limit=200)[0]
    return fresnel_t(ti, tt, eta) / eta**2 * out


@pytest.fixture(scope="module")
def twin():
    cam = SCENE["camera"]
    return np.array([[twin_pixel(i, j) for i in range(cam["width"])] for j in range(cam["height"])])


def image(method, params=None, seed=0):
    prep = prepare(scene_from_text(to_toml(SCENE), "cube_of_water"))
    return render(prep, method, params or {}, RenderOptions(threads=1, seed=seed))


def test_the_scene_has_two_beams_that_overlap():
    """Not vacuous: the sun enters through three faces, and some camera segments are lit by two."""
    assert len(beams(1.33)) == 3
    shared = 0
    for i in range(12):
        for j in range(9):
            o, d = oracle.camera_ray(SCENE["camera"], i, j)
            t0, n_in = box_entry(o, d, LO, HI)
            if n_in is None:
                continue
            w, _, _ = snell(d, n_in, 1.33)
            ell, _ = oracle.box_exit(o + t0 * d, w, LO, HI)
            X = o + t0 * d + 0.5 * ell * w
            shared += sum(reaches(X, n, t) for n, t, _ in beams(1.33)) > 1
    assert shared > 0


@pytest.mark.parametrize("method, tol", [("quadrature", 1e-9), ("analytic", 1e-9)])
def test_every_face_refracts_its_own_beam(twin, method, tol):
    lit = twin[..., 1] > 0
    assert np.count_nonzero(lit) >= 40
    res = image(method)
    rel = np.abs(res.image[lit] - twin[lit]) / twin[lit]
    assert np.max(rel) < tol
    if method == "analytic":  # exact and bounded, no longer eq. 5's infinite bound
        assert np.all(np.isfinite(res.error_bound[lit]))
        assert np.all(np.abs(res.image[lit] - twin[lit]) <= res.error_bound[lit] + 1e-15 * twin[lit])


def test_the_entry_plane_model_is_far_off_here(twin):
    """slab_approx keeps the note's entry plane: eq. 5's beam for the face seen, for the whole segment."""
    lit = twin[..., 1] > 0
    planar = image("slab_approx").image
    assert np.max(np.abs(planar[lit] - twin[lit]) / twin[lit]) > 0.1


def test_raymarch_and_montecarlo_follow_the_beams(twin):
    """The midpoint rule converges to the twin (first order at the beams' edges, second elsewhere);
    free-path samples are unbiased with their own variance (mean squared z-score about 1)."""
    lit = twin[..., 1] > 0
    errs = [np.max(np.abs(image("raymarch", {"steps": n}).image[lit] - twin[lit]) / twin[lit]) for n in (256, 1024)]
    assert errs[1] < 2e-3 and errs[1] < errs[0] / 2.5, errs
    res = image("montecarlo", {"samples": 64}, seed=3)
    z2 = np.mean((res.image[lit] - twin[lit]) ** 2 / res.variance[lit])
    assert 0.3 < z2 < 3.5, z2


def test_with_anything_that_could_shadow_the_beams_the_bound_is_infinite():
    """Inside a refractive shape the beams are not shadowed (docs/bounded_media.md): with an opaque
    plate in the scene the value is no longer known to be exact, and the bound says so."""
    sc = {**SCENE, "shape": SCENE["shape"] + [{"primitive": "quad", "corners": [[-3, -3, -3], [-3, -3, 3], [-3, 3, 3],
                                                                                 [-3, 3, -3]]}]}
    res = render(prepare(scene_from_text(to_toml(sc), "cube_and_plate")), "analytic", {},
                 RenderOptions(threads=1, volumetric_shadows=True))
    alone = image("analytic")
    inside = alone.image[..., 1] > 0
    assert np.all(np.isinf(res.error_bound[inside])) and np.all(np.isfinite(alone.error_bound[inside]))
    assert res.stats["inside: segments unshadowed (refractive or planar model)"] >= np.count_nonzero(inside)
