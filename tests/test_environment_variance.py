"""The environment light's sampling error as a variance (lights/environment.py `points`, rendering/renderer.py
`shade_groups`): each pixel sample's directions are GROUPS groups, each a lattice shifted by uniforms keyed by
(the sample's index, the group, the seed) and folded by the tent, shaded apart; the ray's radiance is their sum
and its variance their spread, added up over the pixel's samples as a stochastic method's.

- Statistics over many seeds against twins built from scipy alone (test_environment.py's): a height fog under a
  constant environment (1 and 4 samples a pixel: the twin of each sample's ray) and under a 2 x 4 map (the
  air-light), a ground point under an opaque plate (the surface term). Each render's value e away from the twin
  and its variance v: the mean of e is 0 (z-test with the seeds' spread) and the variance is the expected square
  error, E[e^2] = E[v] (v is an unbiased estimate of the variance of an unbiased estimate): z-test of the seeds'
  e^2 - v, |z| < 4 (two-sided false alarm 6e-5 each, asymptotically normal over the seeds whatever the groups'
  distribution). (e / sqrt(v) is not N(0, 1): with 2 groups a sample's v has one degree of freedom.)
  SEEDS seeds in the default run (spp 1); `pytest -m slow` runs 256 (spp 1 and 4).
- The plumbing: the image is the other lights' pass plus the groups', sample by sample with each sample's own
  directions, the variance the groups' spread summed over the samples / spp^2 (each group shaded here through
  `Prepared.only`), to 1e-12; the same bytes whatever the thread count and tile size and on two Dask workers
  (slow); progressive passes.
- The points: determinism per (seed, sample), each group's shift uniform and independent of the others'.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, stats

import raytrace
from raytrace import api
from raytrace.camera import generate_rays, pixel_rays
from raytrace.lights import environment
from raytrace.output.film import write_exr
from raytrace.rendering import renderer
from raytrace.rng import uniform

from .test_environment import ENV, FOG, GROUND, PLATE, POINT_CAMERA, UP_CAMERA, fog_twin, scene, texel_of

SEEDS = 64  # the default run's; `-m slow`: 256
L = np.array(ENV["radiance"])
FOG_TWIN = (0.02, 0.1, 2.0)  # sigma_a, sigma_s, scale height of FOG


def errors(sc, twin, seeds, **kw):
    """(e, v): the seeds' renders less the twin, and their variances."""
    imgs = [api.render(sc, "quadrature", seed=seed, **kw) for seed in range(seeds)]
    return np.array([img.array for img in imgs]) - twin, np.array([img.variance for img in imgs])


def assert_variance_is_the_square_error(e, v, positive=True):
    """The mean error within 4 standard errors of 0 per value, and E[e^2] = E[v]: the seeds' mean over values of
    (e^2 - v) / mean(v) within 4 standard errors of 0; every v > 0 where `positive`."""
    sem = e.std(axis=0, ddof=1) / math.sqrt(len(e))
    assert np.all(np.abs(e.mean(axis=0)) < 4.0 * sem), (e.mean(axis=0), sem)
    d = ((e**2 - v) / v.mean(axis=0)).reshape(len(e), -1).mean(axis=1)
    z = d.mean() / (d.std(ddof=1) / math.sqrt(len(d)))
    assert abs(z) < 4.0, (z, np.sum(e**2) / np.sum(v))
    assert np.all(v > 0.0) or not positive


def fog_pixels(sc):
    """The twin of each pixel: the mean of its samples' rays' (fog_twin)."""
    cam = sc.camera
    ys, xs = np.divmod(np.arange(cam.width * cam.height), cam.width)
    origins, dirs = pixel_rays(cam, ys, xs)
    twin = np.array([fog_twin(o, d, L, L, *FOG_TWIN) for o, d in zip(origins, dirs)])
    return twin.reshape(cam.height, cam.width, cam.spp, 3).mean(axis=2)


@pytest.mark.parametrize("spp,seeds", [(1, SEEDS), pytest.param(1, 256, marks=pytest.mark.slow),
                                       pytest.param(4, 256, marks=pytest.mark.slow)])
def test_fog_under_a_constant_environment(spp, seeds):
    sc = scene([ENV], medium=FOG, camera={**UP_CAMERA, "spp": spp})
    assert_variance_is_the_square_error(*errors(sc, fog_pixels(sc), seeds, rtol=1e-10))


@pytest.mark.parametrize("seeds", [SEEDS, pytest.param(256, marks=pytest.mark.slow)])
def test_fog_under_a_map(tmp_path, seeds):
    image = np.array([[[0.1, 0.2, 0.4], [0.4, 0.3, 0.1], [0.9, 0.8, 0.7], [0.2, 0.6, 0.2]], [[3.0, 3.0, 3.0]] * 4])
    write_exr(tmp_path / "sky.exr", image)
    sc = scene([{"type": "environment", "map": "sky.exr"}], medium=FOG, camera=UP_CAMERA, path=tmp_path / "env.toml")
    origins, dirs = generate_rays(sc.camera)
    _, c = texel_of(dirs, np.eye(3), 2, 4)
    twin = np.array([fog_twin(o, d, image[0, k], image[0].mean(axis=0), *FOG_TWIN)
                     for o, d, k in zip(origins, dirs, c)]).reshape(2, 2, 3)
    assert_variance_is_the_square_error(*errors(sc, twin, seeds, rtol=1e-10))


@pytest.mark.parametrize("seeds", [SEEDS, pytest.param(256, marks=pytest.mark.slow)])
def test_a_ground_point_under_a_plate(seeds):
    """The surface term: rho L (1 - F), F the plate's form factor (test_environment.py). Here a variance may be
    0: under a constant sky every direction weighs the same, and the two groups may lose as many to the plate."""
    F = integrate.dblquad(lambda z, x: 1.0 / (math.pi * (x * x + z * z + 1.0) ** 2), -1, 1, -1, 1, epsabs=1e-13)[0]
    sc = scene([ENV], camera=POINT_CAMERA, shapes=[GROUND, PLATE])
    assert_variance_is_the_square_error(*errors(sc, 0.5 * L * (1.0 - F), seeds), positive=False)


CAMERA = {"position": [0.0, 0.5, 3.0], "look_at": [0.0, 1.5, 0.0], "fov": 60.0, "width": 3, "height": 2, "spp": 3}
LAMP = {"position": [0.0, 2.0, 0.0], "intensity": 1.0}


def test_the_variance_is_the_groups_spread(monkeypatch):
    """Fog, a plate, a point light beside the environment, 3 samples a pixel summed in one-sample ranges: each
    sample's rays shaded here with that sample's directions (`renderer.seeded`), the other lights' pass and each
    group's (`Prepared.only`): the image is their sum over the samples / spp, the variance the samples' sum of
    G / (G - 1) sum_g (P_g - P / G)^2 / spp^2, to 1e-12; the samples' directions differ."""
    monkeypatch.setattr(renderer, "SUM_RAYS", 4)
    sc = scene([ENV, LAMP], medium=FOG, camera=CAMERA, shapes=[PLATE])
    img = api.render(sc, "quadrature", seed=7, rtol=1e-8)
    prep = renderer.prepare(sc)
    cam, spp, method = sc.camera, CAMERA["spp"], renderer.get_method("quadrature")
    ys, xs = np.divmod(np.arange(cam.width * cam.height), cam.width)
    image, variance, axes = 0.0, 0.0, []
    for s in range(spp):
        o, d = pixel_rays(cam, ys, xs, slice(s, s + 1))
        keys = (ys * cam.width + xs).astype(np.uint64) * np.uint64(spp) + np.uint64(s)
        view = renderer.seeded(prep, 7, s)
        split = environment.groups(view.lights)
        assert len(split) == environment.GROUPS and np.count_nonzero(split) == environment.COUNT
        axes.append(view.lights.axis[np.any(split, axis=0)])

        def pixels(v):
            return renderer.shade_rays(v, method, {"rtol": 1e-8}, o, d, keys, 7, True)[0].reshape(cam.height,
                                                                                                 cam.width, 3)

        groups = np.array([pixels(view.only(keep)) for keep in split])
        G = len(groups)
        image = image + pixels(view.only(~np.any(split, axis=0), emission=True)) + groups.sum(axis=0)
        variance = variance + G / (G - 1) * ((groups - groups.sum(axis=0) / G) ** 2).sum(axis=0)
    np.testing.assert_allclose(img.array, image / spp, rtol=1e-12)
    np.testing.assert_allclose(img.variance, variance / spp**2, rtol=1e-12)
    assert not np.array_equal(axes[0], axes[1]) and not np.array_equal(axes[1], axes[2])


def test_the_same_bytes_whatever_the_threads(monkeypatch):
    sc = scene([ENV, LAMP], medium=FOG, camera=CAMERA, shapes=[PLATE])
    first = raytrace.render(sc, "quadrature", seed=3, rtol=1e-8, threads=1)
    monkeypatch.setattr(renderer, "RAYS_PER_TILE", 3)
    monkeypatch.setattr(renderer, "PHASES", 5)
    monkeypatch.setattr(renderer, "MIN_TILE_RAYS", 1)
    monkeypatch.setattr(renderer, "SUM_RAYS", 4)
    for threads in (1, 3):
        img = raytrace.render(sc, "quadrature", seed=3, rtol=1e-8, threads=threads)
        for a, b in ((img.array, first.array), (img.variance, first.variance), (img.error_bound, first.error_bound)):
            assert a.tobytes() == b.tobytes(), threads
        assert img.stats == first.stats


def test_progressive_passes_draw_their_own_directions():
    """montecarlo in 3 passes (seeds up to 2^64: progressive.pass_seed): the same bytes with 1 thread or all,
    each pass's directions its own (the image differs from one pass's)."""
    sc = scene([ENV], medium=FOG, camera=UP_CAMERA)
    img = api.render(sc, "montecarlo", samples=4, passes=3, seed=2)
    one = api.render(sc, "montecarlo", samples=4, passes=3, seed=2, threads=1)
    assert img.array.tobytes() == one.array.tobytes() and img.variance.tobytes() == one.variance.tobytes()
    assert np.all(img.variance > 0.0)
    assert not np.array_equal(img.array, api.render(sc, "montecarlo", samples=4, seed=2).array)


@pytest.mark.parametrize("count", [64, 4096, 1000])
def test_each_seed_and_sample_draws_its_own_shifts(count):
    """The points of `count` directions: GROUPS groups of count // GROUPS, each the lattice shifted by the
    group's two uniforms keyed (sample GROUPS + group, seed), then u0 -> 1 - |2 u0 - 1|; the same for a (seed,
    sample), others for another; each group's first point uniform over seeds (Kolmogorov-Smirnov p > 1e-3) and
    independent between groups and samples."""
    groups = environment.points(count, 5, 3)
    assert [len(g) for g in groups] == [count // environment.GROUPS] * environment.GROUPS
    for g, pts in enumerate(groups):
        key = 3 * environment.GROUPS + g
        shift = np.array([uniform(key, environment.DIM_SHIFT, 5), uniform(key, environment.DIM_SHIFT + 1, 5)])
        u = np.mod(environment.lattice(len(pts)) + shift, 1.0)
        np.testing.assert_array_equal(pts, np.stack([1.0 - np.abs(2.0 * u[:, 0] - 1.0), u[:, 1]], axis=1))
    assert all(np.array_equal(a, b) for a, b in zip(groups, environment.points(count, 5, 3)))
    for other in (environment.points(count, 6, 3), environment.points(count, 5, 4)):
        assert not any(np.array_equal(a, b) for a, b in zip(groups, other))
    first = np.array([[g[0] for s in range(2) for g in environment.points(count, seed, s)]
                      for seed in range(400)])  # (seeds, 2 G, 2)
    for g in range(first.shape[1]):
        for k in range(2):
            assert stats.kstest(first[:, g, k], "uniform").pvalue > 1e-3
    corr = np.corrcoef(first[:, :, 0].T)[np.triu_indices(first.shape[1], 1)]
    assert np.all(np.abs(corr) < 4.0 / math.sqrt(len(first))), corr


@pytest.mark.slow
def test_a_cluster_gives_the_threaded_bytes(monkeypatch):
    """Two local Dask workers, small tiles and one-sample ranges: the image and variance of 3 samples a pixel are
    the threads' bytes (each worker draws every sample's directions from the seed and the sample index)."""
    pytest.importorskip("distributed")
    from raytrace.rendering.distributed import connect

    monkeypatch.setattr(renderer, "RAYS_PER_TILE", 2)
    monkeypatch.setattr(renderer, "SUM_RAYS", 3)
    sc = scene([ENV, LAMP], medium=FOG, camera=CAMERA, shapes=[PLATE])
    one = raytrace.render(sc, "quadrature", seed=4, rtol=1e-8, threads=2)
    with connect("local:2") as client:
        many = raytrace.render(sc, "quadrature", seed=4, rtol=1e-8, client=client)
    assert one.array.tobytes() == many.array.tobytes() and one.variance.tobytes() == many.variance.tobytes()
