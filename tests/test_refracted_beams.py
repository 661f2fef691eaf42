"""A directional light inside a convex refractive shape enters through every face it meets
(bounded.refracted_beams): a cube of water under a low sun, seen across two lit faces, against an
independent twin.

The twin (Snell and Fresnel by angles, tests/test_bounded_media.py) refracts the sun through each
face that faces it, follows each refracted beam back from every point of the camera's inside segment
to the cube's wall by the slab test, keeps it where that wall is the face it entered by, and
integrates with scipy `quad` between the points where a beam starts or stops reaching the segment
(bisected on its indicator). With black plates beside the cube and inside it, the indicator also
asks whether the beam's leg inside the cube and its entry point's path to the sun cross a plate. The entry-plane model of the slab note (eq. 5) is off by over 10 % on
these pixels, so the test tells the two apart.
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


def switches(p, w, ell, on_at, samples=400):
    """The x in (0, ell) where the indicator `on_at(X)` changes along p + x w, bisected to doubles."""
    xs = np.linspace(0.0, ell, samples + 1)
    on = [on_at(p + x * w) for x in xs]
    out = []
    for i in np.nonzero(np.array(on[:-1]) != np.array(on[1:]))[0]:
        a, b = xs[i], xs[i + 1]
        while b - a > 4e-16 * ell:
            m = 0.5 * (a + b)
            if on_at(p + m * w) == on[i]:
                a = m
            else:
                b = m
        out.append(0.5 * (a + b))
    return out


def plate_hit(o, d, plate):
    """Distance along the ray (o, d) to the axis-aligned plate (axis, value, lo, hi), or inf."""
    a, v, lo, hi = plate
    if d[a] == 0.0:
        return math.inf
    t = (v - o[a]) / d[a]
    x = o + t * d
    rest = [k for k in range(3) if k != a]
    inside = all(lo[m] <= x[k] <= hi[m] for m, k in enumerate(rest))
    return t if t > 0.0 and inside else math.inf


def plate_shape(plate):
    """The plate as a black quad of the scene format."""
    a, v, lo, hi = plate
    rest = [k for k in range(3) if k != a]
    corners = []
    for u, w in [(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])]:
        c = [0.0, 0.0, 0.0]
        c[a], c[rest[0]], c[rest[1]] = v, u, w
        corners.append(c)
    return {"primitive": "quad", "corners": corners, "reflectance": 0.0}


def twin_pixel(i, j, plates=(), inner_plates=()):
    """The pixel's inside single scattering; `plates`: black plates outside the cube, `inner_plates`:
    inside it, shadowing each beam's path inside and its entry point's path to the sun."""
    inner = SCENE["shape"][0]["interior"]
    eta, g = inner["ior"], inner["phase"]["g"]
    ks = np.array(inner["sigma_s"], float)
    kt = np.array(inner["sigma_a"], float) + ks
    sun = np.array(SUN["direction"], float) / np.linalg.norm(SUN["direction"])
    o, d = oracle.camera_ray(SCENE["camera"], i, j)
    t0, n_in = box_entry(o, d, LO, HI)
    if n_in is None or min([plate_hit(o, d, q) for q in plates] + [math.inf]) < t0:
        return np.zeros(3)
    p = o + t0 * d
    w, ti, tt = snell(d, n_in, eta)
    ell = min([oracle.box_exit(p, w, LO, HI)[0]] + [plate_hit(p, w, q) for q in inner_plates])
    out = np.zeros(3)
    for n, t, e_in in beams(eta):
        def inside_clear(X):  # the beam's leg inside the cube crosses no plate
            k, _ = oracle.box_exit(X, -t, LO, HI)
            return not any(plate_hit(X, -t, q) < k for q in inner_plates)

        def entry_clear(X):  # its entry point sees the sun
            k, _ = oracle.box_exit(X, -t, LO, HI)
            return not any(plate_hit(X - k * t, -sun, q) < math.inf for q in plates)

        def lit(X):
            return reaches(X, n, t) and inside_clear(X) and entry_clear(X)

        phase = oracle.phase("hg", g, float(-(t @ w)))
        # each indicator apart has wide pieces; where two overlap, their lit piece may be narrow
        cuts = [x for on_at in (lambda X: reaches(X, n, t), inside_clear, entry_clear) for x in switches(p, w, ell, on_at)]
        edges = [0.0, *sorted(cuts), ell]
        for a, b in zip(edges, edges[1:]):
            if not lit(p + 0.5 * (a + b) * w):
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
    # bounded, no longer eq. 5's infinite bound (quadrature: each beam against its closed form's bound)
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


OUTER = (0, -1.6, (-0.2, -1.5), (1.5, 0.4))  # x = -1.6 beside the sunlit -x face, y in [-0.2, 1.5], z in [-1.5, 0.4]
INNER = (1, 0.3, (-0.6, -0.5), (0.4, 0.5))  # y = 0.3 inside the cube, x in [-0.6, 0.4], z in [-0.5, 0.5]
SHADOWED = {**SCENE, "shape": SCENE["shape"] + [plate_shape(OUTER), plate_shape(INNER)]}


@pytest.fixture(scope="module")
def shadowed_twin():
    cam = SCENE["camera"]
    return np.array([[twin_pixel(i, j, (OUTER, INNER), (INNER,)) for i in range(cam["width"])]
                     for j in range(cam["height"])])


def shadowed(method, params=None, seed=0, shadows=True):
    prep = prepare(scene_from_text(to_toml(SHADOWED), "cube_and_plates"))
    return render(prep, method, params or {}, RenderOptions(threads=1, seed=seed, volumetric_shadows=shadows))


def test_the_plates_shadow_the_beams(shadowed_twin, twin):
    """Not vacuous: the plate outside shadows part of the sunlit faces, the one inside part of the
    beams' paths, and the shadows change the pixels by far more than the tolerance."""
    lit = shadowed_twin[..., 1] > 0
    assert np.count_nonzero(lit) >= 30
    off = np.abs(shadowed_twin[lit] - twin[lit]) / twin[lit]
    assert np.count_nonzero(off > 1e-2) >= 10, np.sort(off.ravel())[-10:]


@pytest.mark.parametrize("method", ["quadrature", "analytic"])
def test_the_beams_take_volumetric_shadows(shadowed_twin, method):
    """Shadows inside a refractive shape (shadows/beams.py): the beams' legs inside the cube past the
    plate inside it, and their entry points' paths to the sun past the plate beside it, within 1e-9
    of the twin on every pixel; the bound holds and stays finite; unshadowed is far off."""
    res = shadowed(method)
    lit = shadowed_twin[..., 1] > 0
    scale = np.max(shadowed_twin)
    err = np.abs(res.image - shadowed_twin)
    assert np.max(err[lit] / shadowed_twin[lit]) < 1e-9 and np.max(err[~lit]) < 1e-12 * scale
    assert np.all(np.isfinite(res.error_bound[lit]))
    assert np.all(err[lit] <= res.error_bound[lit] + 1e-15 * shadowed_twin[lit])
    assert res.stats.get("inside: segments unshadowed (refractive or planar model)", 0) == 0
    bare = shadowed(method, shadows=False).image
    assert np.max(np.abs(bare[lit] - shadowed_twin[lit]) / shadowed_twin[lit]) > 0.1


def test_raymarch_and_montecarlo_take_the_beams_shadows(shadowed_twin):
    lit = shadowed_twin[..., 1] > 0
    errs = [np.max(np.abs(shadowed("raymarch", {"steps": n}).image[lit] - shadowed_twin[lit]) / shadowed_twin[lit])
            for n in (256, 1024)]
    assert errs[1] < 5e-3 and errs[1] < errs[0] / 2.5, errs
    res = shadowed("montecarlo", {"samples": 64}, seed=3)
    z2 = np.mean((res.image[lit] - shadowed_twin[lit]) ** 2 / res.variance[lit])
    assert 0.3 < z2 < 3.5, z2


def test_a_point_light_in_the_shape_is_shadowed_too():
    """A point light's refracted paths into the cube take the plate's shadow too (shadows/fermat_legs.py,
    against a twin in test_refracted_shadows.py): with the sun, no segment is counted unshadowed, and
    the lamp adds to the shadowed sun as that lamp alone, shadowed, would; the plate changes it."""
    lamp = {"type": "point", "position": [-2.5, 2.5, 0.0], "intensity": 4.0}

    def run(lights, shadows):  # the outer plate only
        sc = {**SCENE, "shape": SCENE["shape"] + [plate_shape(OUTER)], "light": lights}
        return render(prepare(scene_from_text(to_toml(sc), "cube_plates_lamp")), "quadrature", {},
                      RenderOptions(threads=1, volumetric_shadows=shadows))
    both = run([SUN, lamp], True)
    assert both.stats["inside: segments unshadowed (refractive or planar model)"] == 0
    alone = run([lamp], True).image
    assert np.allclose(both.image, run([SUN], True).image + alone, rtol=1e-12, atol=0.0)
    bare = run([lamp], False).image
    assert np.max(np.abs(alone - bare) / np.maximum(bare, 1e-300)) > 0.05
