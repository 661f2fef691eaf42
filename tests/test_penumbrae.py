"""Penumbrae of area lights in the surface term (eq. 5): where occluders cut the emitter, stratified
samples of it with shadow rays (raytrace/shading.py `penumbra`), their variance in the variance layer.

- Each kind's `sample_emitter` (raytrace/lights/) maps the unit square onto its emitter uniformly in
  area: the points lie on it, the density is 1 / A, and the sample moments equal the emitter's
  (scipy/closed forms).
- A floor under a quad light with an opaque plate casting a penumbra, no medium, against a twin from
  the geometry alone (the emitter a quad light, or the same quad as an emissive shape): per pixel,
  rho / pi L times the integral of h^2 / r^4 over the visible part of the emitter (the plate's
  shadow on the emitter is a rectangle: the emitter minus its clip, each by scipy dblquad). Pixels
  outside the penumbrae equal the fixed rule bit for bit and the twin to the rule's accuracy; the
  sampled ones pass a z-test with the reported variance and converge with more samples.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from raytrace import api, shading
from raytrace.lights import Lights, cubature, emissive
from raytrace.scene.format import scene_from_text

from . import area_twin as twin
from .conftest import to_toml

FLOOR = {"primitive": "quad", "corners": [[-2.5, 0.0, 2.5], [2.5, 0.0, 2.5], [2.5, 0.0, -2.5], [-2.5, 0.0, -2.5]],
         "reflectance": 0.5}
PLATE_X, PLATE_Z, PLATE_Y = (-0.2, 0.6), (-0.4, 0.4), 1.0  # an opaque plate, off the light's axis
PLATE = {"primitive": "quad", "reflectance": 0.5,
         "corners": [[PLATE_X[0], PLATE_Y, PLATE_Z[0]], [PLATE_X[1], PLATE_Y, PLATE_Z[0]],
                     [PLATE_X[1], PLATE_Y, PLATE_Z[1]], [PLATE_X[0], PLATE_Y, PLATE_Z[1]]]}
H, L, RHO = 2.0, 10.0, 0.5  # the light's height, radiance; the floor's reflectance
LIGHT = {"type": "quad", "corners": [[-0.5, H, -0.5], [0.5, H, -0.5], [0.5, H, 0.5], [-0.5, H, 0.5]], "radiance": L}
# below the plate, looking down at the floor: every pixel sees the floor or nothing
CAMERA = {"position": [0.0, 0.9, 3.0], "look_at": [0.3, 0.0, 0.0], "fov": 60.0, "width": 32, "height": 24}
SEEDS = 8


# the same emitter as an emissive shape (its two triangles, 7 rows each; sampled by area over both)
EMISSIVE = {"primitive": "quad", "corners": LIGHT["corners"], "emission": L}


def floor_scene(camera=CAMERA, emissive=False):
    lights = {"shape": [FLOOR, PLATE, EMISSIVE]} if emissive else {"shape": [FLOOR, PLATE], "light": [LIGHT]}
    return scene_from_text(to_toml({"camera": camera, **lights}), "penumbra.toml")


def _rectangle(x, z, a, b):
    """The integral of h^2 / r^4 over the emitter's rectangle a x b (in x and z) seen from (x, 0, z)."""
    if a[1] <= a[0] or b[1] <= b[0]:
        return 0.0
    f = lambda bz, ax: H * H / ((ax - x) ** 2 + H * H + (bz - z) ** 2) ** 2  # noqa: E731
    return integrate.dblquad(f, a[0], a[1], b[0], b[1], epsabs=1e-14, epsrel=1e-12)[0]


def twin_radiance(x, z):
    """rho / pi L times the integral over the part of the emitter seen from the floor point (x, 0, z):
    the emitter point (a, H, b) is hidden when the segment crosses the plate's height inside it, that
    is a in 2 PLATE_X - x, b in 2 PLATE_Z - z (PLATE_Y = H / 2): the emitter minus that rectangle."""
    assert PLATE_Y == H / 2
    hidden = [(max(-0.5, 2 * lo - c), min(0.5, 2 * hi - c)) for (lo, hi), c in ((PLATE_X, x), (PLATE_Z, z))]
    return RHO / math.pi * L * (_rectangle(x, z, (-0.5, 0.5), (-0.5, 0.5)) - _rectangle(x, z, *hidden))


@pytest.fixture(autouse=True, scope="module")
def fixed_rule():
    """The emitters' former fixed rules (quad 8 x 8, each triangle's 7 points): the pilot's ladder
    narrowed to them, as the checks here are of the sampling, bit for bit against the rule's image."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(cubature, "AREA_LADDER", (8,))
        mp.setattr(cubature, "LEVELS", 1)
        yield


@pytest.fixture(scope="module")
def reference():
    """The twin at each pixel centre whose ray meets the floor (NaN elsewhere)."""
    o = np.array(CAMERA["position"])
    dirs = twin.camera_rays(o, CAMERA["look_at"], [0.0, 1.0, 0.0], CAMERA["fov"], CAMERA["width"], CAMERA["height"])
    ref = np.full(dirs.shape[:2], np.nan)
    for (i, j), w in np.ndenumerate(dirs[..., 0]):
        w = dirs[i, j]
        p = o - o[1] / w[1] * w if w[1] < 0.0 else None
        if p is not None and max(abs(p[0]), abs(p[2])) <= 2.5:
            ref[i, j] = twin_radiance(p[0], p[2])
    return ref


def renders(scene, seeds=SEEDS, **params):
    """(images (seeds, H, W), variances) of quadrature's red channel with seeds 1..seeds."""
    runs = [api.render(scene, "quadrature", seed=s, **params) for s in range(1, seeds + 1)]
    assert all(np.all(np.isinf(r.error_bound[r.array[..., 0] > 0])) for r in runs)  # the cubature's, as before
    return np.array([r.array[..., 0] for r in runs]), np.array([r.variance[..., 0] for r in runs])


def z_test(images, variances, ref, sampled):
    """(mean z^2, share beyond 4, max |z|) of the seeds' mean against the twin on the sampled pixels,
    the variance of the mean sum(var) / seeds^2."""
    n = len(images)
    z = (images.mean(0) - ref)[sampled] / np.sqrt(variances.sum(0)[sampled] / n**2)
    return np.mean(z**2), np.mean(np.abs(z) > 4.0), np.abs(z).max()


@pytest.mark.parametrize("light", [LIGHT, {"type": "disk", "center": [0.0, 2.0, 0.0], "normal": [0.0, -1.0, 0.0],
                                           "radius": 0.5, "radiance": 1.0},
                                   {"type": "sphere", "center": [0.0, 2.0, 0.0], "radius": 0.3, "radiance": 1.0}])
def test_each_kind_samples_its_emitter_uniformly_in_area(light):
    """A stratified grid of (u, v) (64 x 64 cell centres): the points lie on the emitter, the density
    is 1 / A, the normals are the emitter's, and the mean of x, x^2 and y z over the points equals
    their mean over the emitter (closed forms) to the grid's midpoint error."""
    (emitter,) = Lights.of(scene_from_text(to_toml({"camera": CAMERA, "light": [light]}), "kind.toml").lights).emitters
    g = (np.arange(64) + 0.5) / 64
    u, v = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
    points, normals, density = emitter.sample(u, v)
    c = np.array(light.get("center", [0.0, H, 0.0]))
    rel = points - c
    if light["type"] == "quad":
        area, moments = 1.0, (0.0, 1.0 / 12.0, 0.0)  # x, x^2, (y - c) (z - c) over [-1/2, 1/2]^2
        assert np.all(rel[:, 1] == 0.0) and np.all(normals == [0.0, -1.0, 0.0])
    elif light["type"] == "disk":
        area, moments = math.pi * 0.25, (0.0, 0.25 / 4.0, 0.0)  # x^2: R^2 / 4
        assert np.all(np.abs(rel[:, 1]) < 1e-15) and np.all(np.hypot(rel[:, 0], rel[:, 2]) <= 0.5 + 1e-15)
    else:
        area, moments = 4.0 * math.pi * 0.09, (0.0, 0.09 / 3.0, 0.0)
        np.testing.assert_allclose(np.linalg.norm(rel, axis=1), 0.3, rtol=1e-15)
        np.testing.assert_allclose(normals, rel / 0.3, atol=1e-15)
    np.testing.assert_allclose(density, 1.0 / area, rtol=1e-15)
    got = (rel[:, 0].mean(), (rel[:, 0] ** 2).mean(), (rel[:, 1] * rel[:, 2]).mean())
    np.testing.assert_allclose(got, moments, atol=2e-4)


def test_an_emissive_mesh_is_sampled_uniformly_in_area():
    """Two triangles of areas 1/2 and 2 (one shape): a fifth of the samples in the first, and the
    mean of x, y, x^2 over the samples equals scipy's integrals over the triangles divided by the area (to 1e-3);
    the probes lie inside each triangle, near its corners."""
    tri = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                    [[2.0, 0.0, 0.0], [4.0, 0.0, 0.0], [2.0, 2.0, 0.0]]])
    emitter = emissive.emitter(tri, [1.0, 1.0, 1.0], False)
    g = (np.arange(256) + 0.5) / 256
    u, v = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
    points, normals, density = emitter.sample(u, v)
    np.testing.assert_allclose(density, 1.0 / 2.5, rtol=1e-15)
    assert np.all(normals == [0.0, 0.0, 1.0]) and abs(np.mean(points[:, 0] < 1.5) - 0.2) < 1e-3

    def integral(f):
        return sum(integrate.dblquad(lambda y, x: f(x, y), x0, x0 + s, 0.0, lambda x, x0=x0, s=s: x0 + s - x)[0]
                   for x0, s in ((0.0, 1.0), (2.0, 2.0))) / 2.5

    for f in (lambda x, y: x, lambda x, y: y, lambda x, y: x * x):
        assert abs(f(points[:, 0], points[:, 1]).mean() / integral(f) - 1) < 1e-3
    probes, _ = emitter.probes
    assert np.abs(probes - tri.reshape(-1, 3)).max() < 1e-5


@pytest.mark.parametrize("emissive, rule_tol", [(False, 1e-12), (True, 1e-4)], ids=["quad light", "emissive quad"])
def test_penumbrae_against_the_twin(reference, monkeypatch, emissive, rule_tol):
    """The floor's 32 x 24 pixels, quadrature, 8 seeds, every sampled point at 8 x 8 strata (LADDER
    narrowed to (8,)): pixels the sampling left alone (variance 0 in every seed) are the same in every
    seed, equal the fixed rule's image bit for bit and the twin to 1e-12 (the quad light's 8 x 8 rule;
    the emissive quad's two 7-point rules: 1e-4); the sampled ones (the penumbra) pass a z-test of the
    seeds' mean against the twin with the reported variance (conservative: mean z^2 between 0.3 and
    1.5, at most 1 % beyond 4 sigma, none beyond 8); with 16 x 16 strata the error shrinks (rms 2 x
    smaller at least) and the z-test holds."""
    scene = floor_scene(emissive=emissive)
    floor = ~np.isnan(reference)
    monkeypatch.setattr(shading, "LADDER", (8,))
    images, variances = renders(scene)
    sampled = np.any(variances > 0.0, axis=0)
    assert 60 <= np.count_nonzero(sampled & floor) and not np.any(sampled & ~floor)
    still = floor & ~sampled
    assert np.all(images[:, still] == images[0][still])
    np.testing.assert_allclose(images[0][still], reference[still], rtol=rule_tol, atol=0)
    with monkeypatch.context() as mp:
        mp.setattr(shading, "_cut", lambda *a: np.zeros(len(a[1]), dtype=bool))  # the fixed rule everywhere
        fixed = api.render(scene, "quadrature", seed=1).array[..., 0]
    np.testing.assert_array_equal(images[0][~sampled], fixed[~sampled])
    mean_z2, beyond, worst = z_test(images, variances, reference, sampled)
    assert 0.3 < mean_z2 < 1.5 and beyond <= 0.01 and worst < 8.0, (mean_z2, beyond, worst)
    rms = np.sqrt(np.mean((images.mean(0) - reference)[sampled] ** 2))
    monkeypatch.setattr(shading, "LADDER", (16,))
    fine_images, fine_variances = renders(scene)
    mean_z2, beyond, worst = z_test(fine_images, fine_variances, reference, sampled)
    assert 0.3 < mean_z2 < 1.5 and beyond <= 0.01 and worst < 8.0, (mean_z2, beyond, worst)
    fine_rms = np.sqrt(np.mean((fine_images.mean(0) - reference)[sampled] ** 2))
    assert fine_rms < rms / 2, (rms, fine_rms)


def test_the_sampling_effort_follows_the_precision(reference, monkeypatch):
    """The quad light's floor at rtol 1e-1 and 1e-3, 8 seeds each: the pilot (2 x 2 strata per point)
    gives the sampled points more strata at the finer tolerance (on average at least 1.5 x per side;
    some at the floor, 4 x 4, at 1e-1, most at the cap, 16 x 16, at 1e-3); the reported variance stays
    honest at both (the z-test above against the twin) and the rms error of the sampled pixels falls
    at least 2 x."""
    chosen = {}

    def spy(value, var, tol):
        strata = choose(value, var, tol)
        chosen.setdefault(tol, []).extend(strata.tolist())
        return strata

    choose = shading.choose_strata
    monkeypatch.setattr(shading, "choose_strata", spy)
    scene = floor_scene()
    rms = {}
    for rtol in (1e-1, 1e-3):
        images, variances = renders(scene, rtol=rtol)
        sampled = np.any(variances > 0.0, axis=0)
        assert np.count_nonzero(sampled) >= 60
        mean_z2, beyond, worst = z_test(images, variances, reference, sampled)
        assert 0.3 < mean_z2 < 1.5 and beyond <= 0.01 and worst < 8.0, (rtol, mean_z2, beyond, worst)
        rms[rtol] = np.sqrt(np.mean((images.mean(0) - reference)[sampled] ** 2))
    loose, fine = (np.array(chosen[t]) for t in (1e-1, 1e-3))
    assert fine.mean() >= 1.5 * loose.mean(), (loose.mean(), fine.mean())
    assert np.any(loose == shading.LADDER[0]) and np.mean(fine == shading.LADDER[-1]) > 0.5
    assert rms[1e-3] < rms[1e-1] / 2, rms
