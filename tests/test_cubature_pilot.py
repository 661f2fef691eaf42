"""The cubature pilot's costs cut without changing what it chooses (raytrace/lights/cubature.py,
raytrace/rendering/renderer.py):

- `choose` shades each order it visits once, every pilot ray in one pass (the near rays, which do not
  choose the order, with the deciding ones), and returns what the same rule with every pilot ray
  shaded at every order returns (a twin written here);
- `pilot_pixels` measures only the candidates that may be among the nearest (`nearest`: the same
  distances and order as `distances` on all, of all rays or of those beyond a floor) and reuses them
  for the pilot rays: the same pixels and near rays as distances measured afresh on the pilot's own
  rays (and np.unique over rows), on images smaller and larger than the candidates' grid; a flat
  emitter's near pixels are the nearest beyond cubature.PASSING, its near rays those within it;
- `passes` (a flat emitter's near rays in the render) measures the rays the bounding sphere cannot
  clear: the same rays as `distances` on all;
- the warm-up runs once per scene file, method, parameters and shadows in a process: a second
  render of the same file compiles nothing and gives the same image, a changed file warms up again.
"""
from __future__ import annotations

import os

import numpy as np
import pytest

from raytrace import api
from raytrace.camera import pixel_rays
from raytrace.lights import Lights, cubature, cubature_ladders
from raytrace.scene.format import load_scene

from .test_area_cubature import distances, quad_rows

SCENE = os.path.join(os.path.dirname(__file__), "data", "area_peers", "occluded.toml")


def every_ray_choose(ladders, counts, near, shade, tol):
    """The rule with every pilot ray shaded at every order visited (the twin)."""
    chosen, capped, n_near, stray = [None if l is None else l[0] for l in ladders], 0, 0, 0
    for s, orders in enumerate(ladders):
        if orders is None:
            continue
        decide = ~near[s] if not near[s].all() else near[s]
        at = lambda o: shade(tuple(chosen[:s]) + (o,) + tuple(chosen[s + 1:]))  # noqa: E731
        for coarse, fine in cubature.pairs(orders, counts[s]):
            ok = cubature.agree(at(coarse)[decide], at(fine)[decide], cubature.SHARE * tol)
            if ok.all():
                chosen[s] = coarse
                break
        else:
            chosen[s] = orders[-1]
            capped += 1
        n_near += int(near[s].sum())
        stray += int(np.count_nonzero(~cubature.agree(at(coarse), at(fine), cubature.SHARE * tol)))
    return tuple(chosen), capped, n_near, stray


@pytest.mark.parametrize("seed", range(6))
def test_choose_shades_each_order_once(seed):
    rng = np.random.default_rng(seed)
    n = 12
    exact = rng.uniform(0.5, 2.0, (n, 3))
    rates = rng.uniform(1.0, 12.0, (n, 1))
    near = rng.uniform(size=n) < 0.3
    orders = cubature.ladder(cubature.AREA_LADDER, quad_rows)
    calls = []

    def shade(orders_, rays=None):
        calls.append((orders_[0], None if rays is None else tuple(rays)))
        value = exact * (1.0 + float(orders_[0]) ** -rates)
        return value if rays is None else value[rays]

    for tol in (1e-1, 1e-3):
        calls.clear()
        got = cubature.choose([orders], [quad_rows], [near], shade, tol)
        passes = list(calls)
        assert got == every_ray_choose([orders], [quad_rows], [near], lambda o: shade(o), tol)
        visited = [o for o, _ in passes]
        assert len(visited) == len(set(visited)) >= 2  # each order once
        assert all(rays == tuple(range(n)) for _, rays in passes)  # every ray in each pass


@pytest.mark.parametrize("size", [(32, 24), (7, 5), (128, 96), (200, 150)])
def test_pilot_pixels_as_measured_afresh(size):
    sc = load_scene(SCENE)
    cam = sc.camera
    cam.width, cam.height = size
    lights = Lights.of(sc.lights, [])
    ladders, _ = cubature_ladders(sc.lights)

    def rays_of(pixels):
        return pixel_rays(cam, pixels[:, 0].astype(float), pixels[:, 1].astype(float), slice(0, 1))

    pixels, near = cubature.pilot_pixels(lights.emitters, ladders, rays_of, *size)
    # the former way: np.unique over rows, the pilot rays' distances measured on their own rays
    cand = np.unique(cubature.grid(cubature.CANDIDATES, *size), axis=0)
    o, d = rays_of(cand)
    sample = lights.emitters[0].sample
    every, diameter = distances(sample, o, d)
    beyond = np.flatnonzero(every >= cubature.PASSING * diameter)  # a flat emitter: its near rays do not choose
    picks = [cubature.grid(cubature.GRID, *size), cand[beyond[np.argsort(every[beyond], kind="stable")
                                                             [:cubature.NEAR]]]]
    want = np.unique(np.concatenate(picks), axis=0)
    dist, diameter = distances(sample, *rays_of(want))
    np.testing.assert_array_equal(pixels, want)
    np.testing.assert_array_equal(near[0], dist < cubature.PASSING * diameter)


def test_warm_up_once_per_scene_file(tmp_path):
    kw = dict(width=8, height=6, precision=1e-1, volumetric_shadows=True)
    first = api.render(SCENE, "analytic", **kw)
    second = api.render(SCENE, "analytic", **kw)
    assert second.compile_seconds == 0.0
    np.testing.assert_array_equal(first.array, second.array)
    copy = tmp_path / "occluded.toml"
    copy.write_text(open(SCENE).read())
    assert api.render(str(copy), "analytic", **kw).compile_seconds > 0.0  # another file: warmed up


@pytest.mark.parametrize("beyond", [0.0, 0.25, 1.0])
@pytest.mark.parametrize("seed", range(4))
def test_nearest_measures_every_ray_that_may_be_among_the_nearest(seed, beyond):
    rng = np.random.default_rng(seed)
    sc = load_scene(SCENE)
    sample = Lights.of(sc.lights, []).emitters[0].sample
    n = int(rng.integers(5, 2000))
    o = rng.normal(size=(n, 3)) * rng.uniform(0.3, 5.0)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    every, diameter = distances(sample, o, d)
    some, same_diameter = cubature.nearest(sample, o, d, cubature.NEAR, beyond)
    measured = ~np.isnan(some)
    eligible = every >= beyond * diameter
    assert same_diameter == diameter and measured[eligible].sum() >= min(eligible.sum(), cubature.NEAR)
    np.testing.assert_array_equal(some[measured], every[measured])
    got = np.where(measured & (np.nan_to_num(some) >= beyond * diameter), some, np.inf)
    want = np.argsort(np.where(eligible, every, np.inf), kind="stable")[:cubature.NEAR]
    np.testing.assert_array_equal(np.argsort(got, kind="stable")[:cubature.NEAR][:eligible.sum()],
                                  want[:eligible.sum()])


@pytest.mark.parametrize("fraction", [cubature.NEAR_FRACTION, cubature.PASSING, 2.0])
@pytest.mark.parametrize("seed", range(3))
def test_passes_as_measured_on_every_ray(seed, fraction):
    rng = np.random.default_rng(seed)
    sample = Lights.of(load_scene(SCENE).lights, []).emitters[0].sample
    n = 3000
    o = rng.normal(size=(n, 3)) * rng.uniform(0.3, 3.0)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    every, diameter = distances(sample, o, d)
    want = every < fraction * diameter
    assert 0 < want.sum() < n
    np.testing.assert_array_equal(cubature.passes(sample, o, d, fraction), want)
