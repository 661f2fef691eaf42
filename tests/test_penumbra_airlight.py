"""Penumbrae of area lights in the air-light (raytrace/shadows/penumbra_airlight.py): where occluders
cut the emitter seen along a camera ray, stratified samples of the emitter, each a point light with
its exact lit intervals, integrated by the method itself; their variance in the variance layer.

- Each sample's lit intervals (frusta.point_lit_pieces) against the slow twin of tests/oracle_shadows.py
  (slab tests against boxes, written from the geometry alone), a different light point per segment.
- A quad light over an opaque plate in fog, black floor and plate (the image is the air-light alone),
  against the twin tests/area_twin.py `PlateShadow` (the plate's shadow on the emitter seen from each
  point is a rectangle: the emitter's irradiance less that rectangle's, scipy quad along the ray):
  the rows alone miss the penumbra by far more than the precision and say nothing of it (variance 0);
  with the sampling, pixels left alone equal the rows' image bit for bit and the twin to the
  precision, the sampled ones pass a z-test with the reported variance over 8 seeds, and their
  error falls with the strata; the strata follow the requested precision (a pilot per cut pair), and
  the variance stays honest at a loose and a fine precision.
"""
from __future__ import annotations

import numpy as np
import pytest

from raytrace import api, shading
from raytrace.scene.format import scene_from_text
from raytrace.shadows import penumbra_airlight
from raytrace.shadows.frusta import point_lit_pieces

from . import area_twin as twin
from . import oracle_shadows
from .conftest import to_toml
from .test_exact_shadows import LIGHT, OCCLUDERS, assert_same_pieces, room_scene, segments

H, P, L = 2.0, 1.0, 10.0  # the emitter's height (facing down), the plate's, the radiance
EMITTER = (-0.5, 0.5)  # in x and z
PLATE_X, PLATE_Z = (-0.2, 0.6), (-0.4, 0.4)
FLOOR = 2.5  # half-size of the black floor at y = 0
QUAD = {"type": "quad", "corners": [[-0.5, H, -0.5], [0.5, H, -0.5], [0.5, H, 0.5], [-0.5, H, 0.5]], "radiance": L}
PLATE = {"primitive": "quad", "reflectance": 0.0, "corners": [[PLATE_X[0], P, PLATE_Z[0]], [PLATE_X[1], P, PLATE_Z[0]],
                                                            [PLATE_X[1], P, PLATE_Z[1]], [PLATE_X[0], P, PLATE_Z[1]]]}
GROUND = {"primitive": "quad", "reflectance": 0.0,
          "corners": [[-FLOOR, 0.0, FLOOR], [FLOOR, 0.0, FLOOR], [FLOOR, 0.0, -FLOOR], [-FLOOR, 0.0, -FLOOR]]}
FOG = {"sigma_a": 0.05, "sigma_s": 0.1}
KT, KS = 0.15, 0.1
# under the plate, looking through the shadow's edges; the emitter is out of view
CAMERA = {"position": [0.0, 0.5, 3.0], "look_at": [0.2, 0.4, 0.0], "fov": 40.0, "width": 16, "height": 12}
PRECISION = 1e-6
METHODS = {"analytic": {"precision": PRECISION}, "quadrature": {"rtol": PRECISION}}
SEEDS = 8


def plate_scene():
    return scene_from_text(to_toml({"camera": CAMERA, "shape": [GROUND, PLATE], "light": [QUAD], "medium": FOG}),
                           "plate.toml")


@pytest.fixture(scope="module")
def reference():
    """The twin at every pixel centre (about 3 s)."""
    shadow = twin.PlateShadow(EMITTER, EMITTER, H, L, PLATE_X, PLATE_Z, P, FLOOR)
    o = np.array(CAMERA["position"])
    dirs = twin.camera_rays(o, CAMERA["look_at"], [0.0, 1.0, 0.0], CAMERA["fov"], CAMERA["width"], CAMERA["height"])
    return np.array([[shadow.radiance(o, d, KT, KS) for d in row] for row in dirs])


@pytest.mark.parametrize("name", OCCLUDERS)
def test_each_samples_lit_intervals_against_the_twin(name):
    """Every camera ray of the occluder scenes of test_exact_shadows under its own point light (a
    different one per ray, within 0.3 of the scenes' light): the lit pieces, ends to 1e-12 of the
    scene's size, against the twin's closed-form boundaries; some rays are shadowed."""
    boxes = OCCLUDERS[name]
    prep, segs, _ = segments(room_scene(boxes))
    points = np.array(LIGHT) + np.random.default_rng(5).uniform(-0.3, 0.3, (len(segs), 3))
    ends = segs.origins + segs.length[:, None] * segs.dirs
    box = (np.minimum(np.minimum(points, segs.origins), ends), np.maximum(np.maximum(points, segs.origins), ends))
    src, x0, x1 = point_lit_pieces(prep.accel, segs, points, np.arange(len(segs)), box, None)
    tol = 1e-12 * prep.accel.scale
    shadowed = 0
    for s in range(len(segs)):
        twin_pieces = oracle_shadows.lit_pieces(segs.origins[s], segs.dirs[s], segs.length[s], points[s], boxes)
        assert_same_pieces(list(zip(x0[src == s], x1[src == s])), twin_pieces, tol)
        shadowed += twin_pieces != [(0.0, segs.length[s])]
    assert shadowed > 10


@pytest.mark.parametrize("method", METHODS)
def test_the_rows_alone_miss_the_penumbra_silently(reference, monkeypatch, method):
    """Without the sampling (the rows with their exact intervals everywhere), the penumbra's pixels
    are off by more than 1000 x the precision, and the render says nothing of it: no variance (the
    bound is infinite, the cubature's, but a z-test against the variance layer would pass them as
    exact). This is what the sampling replaces."""
    monkeypatch.setattr(penumbra_airlight, "applies", lambda *a: False)
    img = api.render(plate_scene(), method, volumetric_shadows=True, **METHODS[method])
    rel = np.abs(img.array[..., 0] / reference - 1)
    assert rel.max() > 1000 * PRECISION, rel.max()
    assert np.all(img.variance == 0.0) and np.all(np.isinf(img.error_bound))


def renders(method, seeds=SEEDS):
    """(images (seeds, H, W), variances, error bounds) of the red channel with seeds 1..seeds."""
    runs = [api.render(plate_scene(), method, volumetric_shadows=True, seed=s, **METHODS[method])
            for s in range(1, seeds + 1)]
    return (np.array([r.array[..., 0] for r in runs]), np.array([r.variance[..., 0] for r in runs]),
            np.array([r.error_bound[..., 0] for r in runs]))


def z_scores(images, variances, ref, sampled):
    """The z-scores of each seed's sampled pixels against the twin with their own variance."""
    return ((images - ref) / np.sqrt(np.where(variances > 0.0, variances, np.inf)))[:, sampled]


@pytest.mark.parametrize("method", METHODS)
def test_penumbrae_in_the_airlight_against_the_twin(reference, monkeypatch, method):
    """16 x 12 pixels, 8 seeds: the pixels the sampling left alone (variance 0 in every seed) are the
    same in every seed, equal the rows' image bit for bit and the twin to the precision; the sampled
    ones (at least 60; the bound infinite there) pass a z-test against the twin with the reported
    variance: conservative (mean z^2 of the seeds between 0.1 and 1.5), none beyond 4; every cut pair
    at 8 x 8 strata instead (the precision asks for the cap, 16 x 16, of most) the z-test holds and
    their rms error is at least 2 x larger."""
    images, variances, bounds = renders(method)
    sampled = np.any(variances > 0.0, axis=0)
    assert np.count_nonzero(sampled) >= 60 and np.all(np.isinf(bounds[:, sampled]))
    still = ~sampled
    assert np.all(images[:, still] == images[0][still])
    np.testing.assert_allclose(images[0][still], reference[still], rtol=PRECISION, atol=0)
    monkeypatch.setattr(penumbra_airlight, "applies", lambda *a: False)
    rows = api.render(plate_scene(), method, volumetric_shadows=True, seed=1, **METHODS[method]).array[..., 0]
    np.testing.assert_array_equal(images[0][still], rows[still])
    monkeypatch.undo()
    z = z_scores(images, variances, reference, sampled)
    assert 0.1 < np.mean(z**2) < 1.5 and np.abs(z).max() < 4.0, (np.mean(z**2), np.abs(z).max())
    rms = np.sqrt(np.mean((images - reference)[:, sampled] ** 2))
    monkeypatch.setattr(shading, "LADDER", (8,))  # every cut pair at 8 x 8 strata
    coarse, coarse_var, _ = renders(method)
    z = z_scores(coarse, coarse_var, reference, sampled)
    assert 0.1 < np.mean(z**2) < 1.5 and np.abs(z).max() < 4.0, (np.mean(z**2), np.abs(z).max())
    coarse_rms = np.sqrt(np.mean((coarse - reference)[:, sampled] ** 2))
    assert rms < coarse_rms / 2, (coarse_rms, rms)


def test_the_sampling_effort_follows_the_precision(reference, monkeypatch):
    """`analytic` at precision 3e-2 and 1e-3, 8 seeds each: the pilot gives the cut pairs more strata
    at the finer precision (on average at least 1.5 x per side; some pairs at the floor at 3e-2, most at
    the cap at 1e-3); the reported variance stays honest at both (z-test against the twin as above) and
    the rms error of the sampled pixels falls at least 2 x."""
    chosen = {}

    def spy(value, var, tol):
        strata = choose(value, var, tol)
        chosen.setdefault(tol, []).extend(strata.tolist())
        return strata

    choose = shading.choose_strata  # the surfaces' too, but the floor and plate are black: not sampled
    monkeypatch.setattr(shading, "choose_strata", spy)
    rms = {}
    for precision in (3e-2, 1e-3):
        runs = [api.render(plate_scene(), "analytic", volumetric_shadows=True, seed=s, precision=precision)
                for s in range(1, SEEDS + 1)]
        images, variances = np.array([r.array[..., 0] for r in runs]), np.array([r.variance[..., 0] for r in runs])
        sampled = np.any(variances > 0.0, axis=0)
        assert np.count_nonzero(sampled) >= 60
        z = z_scores(images, variances, reference, sampled)
        assert 0.1 < np.mean(z**2) < 1.5 and np.abs(z).max() < 4.0, (precision, np.mean(z**2), np.abs(z).max())
        rms[precision] = np.sqrt(np.mean((images - reference)[:, sampled] ** 2))
    loose, fine = (np.array(chosen[p]) for p in (3e-2, 1e-3))
    assert fine.mean() >= 1.5 * loose.mean(), (loose.mean(), fine.mean())
    assert np.any(loose == shading.LADDER[0]) and np.mean(fine == shading.LADDER[-1]) > 0.5
    assert rms[1e-3] < rms[3e-2] / 2, rms


def test_scenes_with_nothing_cut_are_untouched(monkeypatch):
    """The plate moved out of the light's way: no camera ray is sampled, and the image is the rows'
    bit for bit."""
    far = {**PLATE, "corners": [[x + 10.0, y, z] for x, y, z in PLATE["corners"]]}
    sc = scene_from_text(to_toml({"camera": CAMERA, "shape": [GROUND, far], "light": [QUAD], "medium": FOG}),
                         "far.toml")
    img = api.render(sc, "analytic", volumetric_shadows=True, precision=PRECISION)
    monkeypatch.setattr(penumbra_airlight, "applies", lambda *a: False)
    rows = api.render(sc, "analytic", volumetric_shadows=True, precision=PRECISION)
    assert np.all(img.variance == 0.0)
    np.testing.assert_array_equal(img.array, rows.array)
