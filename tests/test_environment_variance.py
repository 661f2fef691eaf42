"""The environment light's sampling error as a variance (lights/environment.py `points`, rendering/renderer.py
`shade_groups` and `Accumulator`): its directions are GROUPS groups, each a lattice shifted by uniforms keyed by
(group, seed) and its mirror, shaded apart; the pixel is their sum and its variance their spread.

- Statistics over many seeds against twins built from scipy alone (test_environment.py's): a height fog under a
  constant environment and under a 2 x 4 map (the air-light) and a ground point under an opaque plate (the
  surface term). Each render's value e away from the twin and its variance v: the mean of e is 0 (z-test with the
  seeds' spread) and the variance is the expected square error, E[e^2] = E[v] (v is an unbiased estimate of the
  variance of an unbiased estimate): z-test of the seeds' e^2 - v, |z| < 4 (two-sided false alarm 6e-5 each,
  asymptotically normal over the seeds whatever the groups' distribution). (e / sqrt(v) is not N(0, 1): with 8
  groups it is Student's t with 7 degrees of freedom where the groups' sums are normal, mean square 1.4, and
  heavier-tailed where a lattice of 8 directions makes them far from normal: 2-6 over 256 seeds here.)
- The plumbing: the variance equals G / (G - 1) sum_g (P_g - P / G)^2 of the groups' pixel means P_g (each
  group shaded here through `Prepared.only`, the pixel's samples in one-sample ranges), the image their sum
  plus the other lights'; the same bytes whatever the thread count and tile size; each seed its own shifts.
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

SEEDS = 256
L = np.array(ENV["radiance"])


def errors(sc, twin, **kw):
    """(e, v): the seeds' renders less the twin, and their variances."""
    imgs = [api.render(sc, "quadrature", seed=seed, **kw) for seed in range(SEEDS)]
    return np.array([img.array for img in imgs]) - twin, np.array([img.variance for img in imgs])


def assert_variance_is_the_square_error(e, v):
    """The mean error within 4 standard errors of 0 per value, and E[e^2] = E[v]: the seeds' mean over values of
    (e^2 - v) / mean(v) within 4 standard errors of 0."""
    sem = e.std(axis=0, ddof=1) / math.sqrt(len(e))
    assert np.all(np.abs(e.mean(axis=0)) < 4.0 * sem), (e.mean(axis=0), sem)
    d = ((e**2 - v) / v.mean(axis=0)).reshape(len(e), -1).mean(axis=1)
    z = d.mean() / (d.std(ddof=1) / math.sqrt(len(d)))
    assert abs(z) < 4.0, (z, np.sum(e**2) / np.sum(v))
    assert np.all(v > 0.0)


def test_fog_under_a_constant_environment():
    sc = scene([ENV], medium=FOG, camera=UP_CAMERA)
    origins, dirs = generate_rays(sc.camera)
    twin = np.array([fog_twin(o, d, L, L, 0.02, 0.1, 2.0) for o, d in zip(origins, dirs)]).reshape(2, 2, 3)
    assert_variance_is_the_square_error(*errors(sc, twin, rtol=1e-10))


def test_fog_under_a_map(tmp_path):
    image = np.array([[[0.1, 0.2, 0.4], [0.4, 0.3, 0.1], [0.9, 0.8, 0.7], [0.2, 0.6, 0.2]], [[3.0, 3.0, 3.0]] * 4])
    write_exr(tmp_path / "sky.exr", image)
    sc = scene([{"type": "environment", "map": "sky.exr"}], medium=FOG, camera=UP_CAMERA, path=tmp_path / "env.toml")
    origins, dirs = generate_rays(sc.camera)
    _, c = texel_of(dirs, np.eye(3), 2, 4)
    twin = np.array([fog_twin(o, d, image[0, k], image[0].mean(axis=0), 0.02, 0.1, 2.0)
                     for o, d, k in zip(origins, dirs, c)]).reshape(2, 2, 3)
    assert_variance_is_the_square_error(*errors(sc, twin, rtol=1e-10))


def test_a_ground_point_under_a_plate():
    """The surface term: rho L (1 - F), F the plate's form factor (test_environment.py)."""
    F = integrate.dblquad(lambda z, x: 1.0 / (math.pi * (x * x + z * z + 1.0) ** 2), -1, 1, -1, 1, epsabs=1e-13)[0]
    sc = scene([ENV], camera=POINT_CAMERA, shapes=[GROUND, PLATE])
    assert_variance_is_the_square_error(*errors(sc, 0.5 * L * (1.0 - F)))


CAMERA = {"position": [0.0, 0.5, 3.0], "look_at": [0.0, 1.5, 0.0], "fov": 60.0, "width": 4, "height": 3, "spp": 3}
LAMP = {"position": [0.0, 2.0, 0.0], "intensity": 1.0}


def test_the_variance_is_the_groups_spread(monkeypatch):
    """Fog, a plate, a point light beside the environment, 3 samples a pixel summed in one-sample ranges: the
    image is the other lights' pass plus the groups' (each shaded here through `Prepared.only`), the variance
    G / (G - 1) sum_g (P_g - P / G)^2 of the groups' pixel means, to 1e-12."""
    monkeypatch.setattr(renderer, "SUM_RAYS", 4)
    sc = scene([ENV, LAMP], medium=FOG, camera=CAMERA, shapes=[PLATE])
    img = api.render(sc, "quadrature", seed=7, rtol=1e-8)
    prep = renderer.seeded(renderer.prepare(sc), 7)
    cam, spp, method = sc.camera, CAMERA["spp"], renderer.get_method("quadrature")
    ys, xs = np.divmod(np.arange(cam.width * cam.height), cam.width)
    o, d = pixel_rays(cam, ys, xs, slice(0, spp))
    keys = ((ys * cam.width + xs)[:, None].astype(np.uint64) * np.uint64(spp) + np.arange(spp, dtype=np.uint64)).ravel()

    def pixels(view):
        rad = renderer.shade_rays(view, method, {"rtol": 1e-8}, o, d, keys, 7, True)[0]
        return rad.reshape(cam.height, cam.width, spp, 3).mean(axis=2)

    split = environment.groups(prep.lights)
    assert len(split) == environment.GROUPS and np.count_nonzero(split) == environment.COUNT
    groups = np.array([pixels(prep.only(keep)) for keep in split])
    rest = pixels(prep.only(~np.any(split, axis=0), emission=True))
    G = len(groups)
    np.testing.assert_allclose(img.array, rest + groups.sum(axis=0), rtol=1e-12)
    np.testing.assert_allclose(img.variance, G / (G - 1) * ((groups - groups.sum(axis=0) / G) ** 2).sum(axis=0),
                               rtol=1e-12)
    assert img.stats["environment: directions"] == environment.COUNT
    assert img.stats["environment: groups"] == environment.GROUPS


def test_the_same_bytes_whatever_the_threads(monkeypatch):
    sc = scene([ENV, LAMP], medium=FOG, camera=CAMERA, shapes=[PLATE])
    first = raytrace.render(sc, "quadrature", seed=3, rtol=1e-8, threads=1)
    monkeypatch.setattr(renderer, "RAYS_PER_TILE", 3)
    monkeypatch.setattr(renderer, "PHASES", 5)
    monkeypatch.setattr(renderer, "MIN_TILE_RAYS", 1)
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
    assert np.all(img.variance > 0.0) and img.stats["environment: groups"] == environment.GROUPS
    assert not np.array_equal(img.array, api.render(sc, "montecarlo", samples=4, seed=2).array)


@pytest.mark.parametrize("count", [64, 4096, 1000])
def test_each_seed_draws_its_own_shifts(count):
    """The points of `count` directions: GROUPS groups of count // GROUPS (or one more), each a lattice shifted
    by the group's two uniforms and its mirror 1 - u0; the same for a seed, others for another; each group's
    first point uniform over seeds (Kolmogorov-Smirnov p > 1e-3) and independent between groups."""
    groups = environment.points(count, 5)
    assert [len(g) for g in groups] == [count * (g + 1) // 8 - count * g // 8 for g in range(environment.GROUPS)]
    for g, pts in enumerate(groups):
        half = environment.lattice((len(pts) + 1) // 2)
        shift = np.array([uniform(g, environment.DIM_SHIFT, 5), uniform(g, environment.DIM_SHIFT + 1, 5)])
        np.testing.assert_array_equal(pts[:len(half)], np.mod(half + shift, 1.0))
        np.testing.assert_allclose(pts[len(half):, 0], 1.0 - pts[:len(pts) // 2, 0], atol=1e-15)
    assert all(np.array_equal(a, b) for a, b in zip(groups, environment.points(count, 5)))
    assert not any(np.array_equal(a, b) for a, b in zip(groups, environment.points(count, 6)))
    first = np.array([[g[0] for g in environment.points(count, seed)] for seed in range(400)])  # (seeds, G, 2)
    for g in range(environment.GROUPS):
        for k in range(2):
            assert stats.kstest(first[:, g, k], "uniform").pvalue > 1e-3
    corr = np.corrcoef(first[:, :, 0].T)[np.triu_indices(environment.GROUPS, 1)]
    assert np.all(np.abs(corr) < 4.0 / math.sqrt(len(first))), corr
