"""Inside a convex refractive shape, the sun's refracted beams are attenuated by another,
index-matched interior on their entry points' way to the sun (shadows/through_others.py with a
beam's face): the cube of water of tests/test_refracted_beams.py with a dense absorbing box above
and beside it, between the sun and part of two of its lit faces.

The twin uses the geometry alone: each face's beam (Snell and Fresnel by angles) followed back from
every point of the camera's inside segment to the cube's wall by the slab test, kept where that wall
is its face; from the entry point, the path toward the sun through the dense box by a slab test,
ks Phi E exp(-kt (x + k)) exp(-kt_B c_B); scipy `quad` between the points where the beam starts or
stops reaching the segment or the faces its path crosses the dense box by change (bisected on those
indicators), and where that path meets an edge of the dense box (solved from the entry point's line).
"""

import numpy as np
import pytest
from scipy import integrate

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import oracle
from .conftest import to_toml
from .test_bounded_media import box_entry, fresnel_t, slab, snell
from .test_refracted_beams import LO, HI, SCENE, SUN, beams, reaches, switches
from .test_through_others import edge_crossings

LO_B, HI_B = np.array([-2.0, 1.4, -1.6]), np.array([-0.2, 2.0, -0.3])
DENSE = {"sigma_a": [1.5, 1.0, 0.5], "sigma_s": [0.0, 0.0, 0.0]}
DENSE_SCENE = {**SCENE, "name": "cube_of_water_beside_a_dense_box",
               "shape": SCENE["shape"] + [{"primitive": "box", "min": LO_B.tolist(), "max": HI_B.tolist(),
                                           "interior": DENSE}]}
TOWARD_SUN = -np.array(SUN["direction"], float) / np.linalg.norm(SUN["direction"])


def dense_chord(P, toward=TOWARD_SUN):
    """(chord, the faces it enters and leaves by) of the path from P toward the sun through the dense box."""
    hit = slab(P, toward, LO_B, HI_B)
    if hit is None or hit[1] <= 0.0:
        return 0.0, None
    leave = [max((LO_B[a] - P[a]) / toward[a], (HI_B[a] - P[a]) / toward[a]) for a in range(3)]
    return hit[1] - max(hit[0], 0.0), (tuple(hit[2]), int(np.argmin(leave)))


def entry(X, n, t):
    """The beam's entry point on face n's plane (n.q = 1) from X, back along -t."""
    return X - ((1.0 - n @ X) / (n @ -t)) * t


def twin_pixel(i, j, dense=True):
    inner = SCENE["shape"][0]["interior"]
    eta, g = inner["ior"], inner["phase"]["g"]
    ks = np.array(inner["sigma_s"], float)
    kt = np.array(inner["sigma_a"], float) + ks
    kt_b = np.array(DENSE["sigma_a"], float) if dense else np.zeros(3)
    o, d = oracle.camera_ray(SCENE["camera"], i, j)
    t0, n_in = box_entry(o, d, LO, HI)
    if n_in is None:
        return np.zeros(3)
    p = o + t0 * d
    w, ti, tt = snell(d, n_in, eta)
    ell = oracle.box_exit(p, w, LO, HI)[0]
    out = np.zeros(3)
    for n, t, e_in in beams(eta):
        phase = oracle.phase("hg", g, float(-(t @ w)))
        P0 = entry(p, n, t)
        line = entry(p + w, n, t) - P0  # the entry point's motion per unit x
        cuts = (switches(p, w, ell, lambda X: reaches(X, n, t))
                + switches(p, w, ell, lambda X: str(dense_chord(entry(X, n, t))[1]))
                + edge_crossings(P0, line, TOWARD_SUN, LO_B, HI_B, ell))
        edges = [0.0, *sorted(cuts), ell]
        for a, b in zip(edges, edges[1:]):
            if not (b > a and reaches(p + 0.5 * (a + b) * w, n, t)):
                continue

            def f(x):
                X = p + x * w
                k, _ = oracle.box_exit(X, -t, LO, HI)
                return ks * phase * e_in * np.exp(-kt * (x + k) - kt_b * dense_chord(X - k * t)[0])
            out += integrate.quad_vec(f, a, b, epsabs=0.0, epsrel=1e-12, norm="max", limit=400)[0]
    return fresnel_t(ti, tt, eta) / eta**2 * out


def twin_image(dense=True):
    cam = SCENE["camera"]
    return np.array([[twin_pixel(i, j, dense) for i in range(cam["width"])] for j in range(cam["height"])])


@pytest.fixture(scope="module")
def twin():
    return twin_image()


def image(method, params=None, seed=0):
    prep = prepare(scene_from_text(to_toml(DENSE_SCENE), DENSE_SCENE["name"]))
    return render(prep, method, params or {}, RenderOptions(threads=1, seed=seed, volumetric_shadows=True))


def test_the_dense_box_shades_part_of_the_beams(twin):
    """Not vacuous: no camera ray crosses the dense box before the cube, and its shade changes many
    pixels by far more than the tolerance while leaving others as they are."""
    cam = SCENE["camera"]
    for i in range(cam["width"]):
        for j in range(cam["height"]):
            o, d = oracle.camera_ray(cam, i, j)
            hit = slab(o, d, LO_B, HI_B)
            assert hit is None or hit[1] < 0.0 or box_entry(o, d, LO, HI)[1] is None
    lit = twin[..., 1] > 0
    assert np.count_nonzero(lit) >= 40
    bare = twin_image(dense=False)
    off = np.abs(bare[lit] - twin[lit]) / twin[lit]
    assert np.count_nonzero(off > 0.05) >= 10 and np.count_nonzero(off < 1e-12) >= 5, np.sort(off)


@pytest.mark.parametrize("rtol", [1e-10, 1e-6])
def test_quadrature_takes_the_dense_box_and_bounds_it(twin, rtol):
    """quadrature matches the twin, its bound finite (before: infinite with any index-matched interior
    in the scene), never exceeded and not vacuous (median at most 10 rtol of the value)."""
    lit = twin[..., 1] > 0
    res = image("quadrature", {"rtol": rtol})
    err = np.abs(res.image - twin)
    assert np.max(err[lit] / twin[lit]) < max(10.0 * rtol, 1e-9), np.max(err[lit] / twin[lit])
    assert np.all(res.image[~lit] == 0.0)
    assert np.all(np.isfinite(res.error_bound)) and np.all(err <= res.error_bound + 1e-12 * twin)
    assert np.median(res.error_bound[lit] / twin[lit]) <= 10.0 * rtol, np.median(res.error_bound[lit] / twin[lit])


def test_analytic_hands_the_shaded_beams_to_quadrature(twin):
    lit = twin[..., 1] > 0
    res = image("analytic")
    err = np.abs(res.image - twin)
    assert np.max(err[lit] / twin[lit]) < 1e-9, np.max(err[lit] / twin[lit])
    assert res.stats["inside: segments handed to quadrature"] >= np.count_nonzero(lit)
    assert np.all(np.isfinite(res.error_bound)) and np.all(err <= res.error_bound + 1e-12 * twin)


def test_raymarch_and_montecarlo_take_the_dense_box(twin):
    """raymarch converges to the twin, montecarlo passes a z-test (their own rules, no bound)."""
    lit = twin[..., 1] > 0
    rel = {n: np.max(np.abs(image("raymarch", {"steps": n}).image - twin)[lit] / twin[lit]) for n in (256, 1024)}
    assert rel[1024] < 2e-3 and rel[1024] < rel[256] / 2.5, rel
    res = image("montecarlo", {"samples": 64}, seed=3)
    z = (res.image - twin)[lit] / np.sqrt(res.variance[lit])
    assert 0.3 < np.mean(z * z) < 3.5, np.mean(z * z)
