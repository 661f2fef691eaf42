"""montecarlo draws each flat emitter's rows over the emitter in its kernels (methods/montecarlo.py
`drawn_segments`, lights/planar.py `emitter_point`): unbiased for the emitter itself, not for its cubature rule.

- The hook: `flat` tells flat emitters (quad, disk, a flat emissive shape) from the rest (a sphere, an
  emissive box); `emitter_point` puts its points on the emitter, uniform in area (chi-square over cells of
  equal area, false alarm 1e-3 per emitter), its pieces' area is the emitter's A (by scipy) and the rows'
  weights of each side sum to A, which makes the row moved to the point an unbiased estimate of its share
  of the emitter.
- Images: rays that pass near the emitter (where the rows' rule is off by several standard errors at 256
  samples) against the exact brute-force twin (tests/area_twin.py, polar about each ray's foot point): over
  4 seeds the z-scores' mean square lies within 4 of its standard deviations of 1 and no |z| exceeds 4.5
  (false alarm below 1e-3 per image); the same pixels with the emissive pair's rows (what the method drew
  before) are off by far more.
- Thread count: the same image, bit for bit, on 1 and 2 threads.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, stats

from raytrace import api
from raytrace.lights import Lights
from raytrace.lights.planar import emitter_pieces, emitter_point, flat, flat_rows

from . import area_twin as twin
from .test_area_lights import DISK, KS, KT, QUAD, SPHERE, scene

# rays that pass 0.08 to 0.26 from the quad (under it, below its plane), none ending on an emitter (on a ray
# that ends on one the estimate's mean square diverges like a log, docs/area_lights.md)
NEAR = {"position": [0.3, 1.3, 1.5], "look_at": [0.0, 1.3, 0.0], "fov": 10.0, "width": 4, "height": 3}
# a convex quadrilateral, not a parallelogram, as two emissive triangles of unequal area (wound to face -y)
PAIR = np.array([[-0.5, 1.5, -0.5], [0.5, 1.5, -0.5], [0.7, 1.5, 0.6], [-0.5, 1.5, 0.5]])
EMISSIVE = {"primitive": "triangles", "vertices": PAIR.tolist(), "faces": [[0, 1, 2], [0, 2, 3]], "emission": 10.0}
N = 40000


def _lights(kind):
    """The `Lights` of one emitter: a scene light, or the emissive pair (two_sided both ways)."""
    if kind == "pair":
        return Lights.of([], [(PAIR[[[0, 1, 2], [0, 2, 3]]], np.full(3, 10.0), True, "shape[0]")])
    return Lights.of(scene([{"quad": QUAD, "disk": {**DISK, "two_sided": True}, "sphere": SPHERE}[kind]]).lights)


def _draw(lights, n=N):
    """(points (n, 3), the area of its pieces) of emitter 0's `emitter_point` for n pairs of uniform numbers."""
    kind, frame, upper, first, last = emitter_pieces(lights)
    uv = np.random.default_rng(7).random((n, 2))
    return np.array([emitter_point(kind, frame, upper, first[0], last[0], u, v) for u, v in uv]), upper[last[0] - 1]


def _chi2(counts, expected):
    return stats.chi2.sf(np.sum((counts - expected) ** 2 / expected), len(counts) - 1)


def test_flat_tells_flat_emitters_from_the_rest():
    assert all(flat_rows(_lights(k)).all() for k in ("quad", "disk", "pair"))
    assert not flat_rows(_lights("sphere")).any()
    box = Lights.of([], [(np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [0, 0, 1], [0, 1, 1]]], float),
                          np.ones(3), False, "shape[0]")])
    assert not flat(box.emitters[0]) and not flat_rows(box).any()


def test_emitter_points_on_a_quad_are_uniform():
    lights = _lights("quad")
    y, pieces = _draw(lights)
    c = np.array(QUAD["corners"], float)
    e1, e3 = c[1] - c[0], c[3] - c[0]
    s, t = (y - c[0]) @ e1 / (e1 @ e1), (y - c[0]) @ e3 / (e3 @ e3)
    counts = np.histogram2d(s, t, bins=8, range=[[0, 1], [0, 1]])[0].ravel()
    assert counts.sum() == N and _chi2(counts, np.full(64, N / 64)) > 1e-3
    area = integrate.dblquad(lambda a, b: np.linalg.norm(np.cross(e1, e3)), 0, 1, 0, 1)[0]
    _area_and_weights(lights, pieces, area)


def test_emitter_points_on_a_disk_are_uniform():
    lights = _lights("disk")
    y, pieces = _draw(lights)
    rel = y - np.array(DISK["center"])
    assert np.abs(rel[:, 1]).max() < 1e-15
    r2 = (rel[:, 0] ** 2 + rel[:, 2] ** 2) / 0.25  # rings of equal area: r^2 / R^2 in eighths
    phi = np.arctan2(rel[:, 2], rel[:, 0])
    counts = np.histogram2d(r2, phi, bins=8, range=[[0, 1], [-math.pi, math.pi]])[0].ravel()
    assert counts.sum() == N and _chi2(counts, np.full(64, N / 64)) > 1e-3
    area = integrate.dblquad(lambda r, p: r, 0, 2 * math.pi, 0, 0.5)[0]
    _area_and_weights(lights, pieces, area)


def test_emitter_points_on_emissive_triangles_are_uniform():
    """The pair by area: each triangle's four midpoint sub-triangles (a corner's: its barycentric > 1/2)."""
    lights = _lights("pair")
    y, pieces = _draw(lights)
    counts, expected = [], []
    for tri in (PAIR[[0, 1, 2]], PAIR[[0, 2, 3]]):
        a = 0.5 * np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0]))
        bary = np.linalg.lstsq(np.vstack([tri.T, np.ones(3)]), np.vstack([y.T, np.ones(N)]), rcond=None)[0].T
        inside = np.all(bary >= -1e-12, axis=1)
        corner = np.argmax(bary, axis=1)
        counts += [np.count_nonzero(inside & (bary.max(axis=1) > 0.5) & (corner == k)) for k in range(3)]
        counts.append(np.count_nonzero(inside & (bary.max(axis=1) <= 0.5)))
        expected += [a / 4] * 4
    expected = np.array(expected) * N / sum(expected)
    assert sum(counts) == N and _chi2(np.array(counts), expected) > 1e-3
    area = sum(integrate.dblquad(lambda b, a, t=t: 2 * 0.5 * np.linalg.norm(np.cross(t[1] - t[0], t[2] - t[0])),
                                 0, 1, 0, lambda a: 1 - a)[0] for t in (PAIR[[0, 1, 2]], PAIR[[0, 2, 3]]))
    _area_and_weights(lights, pieces, area)


def _area_and_weights(lights, pieces, area):
    """The pieces cover the emitter's area A (uniform on them: density 1 / A) and each side's rows weigh A."""
    np.testing.assert_allclose(pieces, area, rtol=1e-12)
    for side in (1.0, -1.0):
        facing = (lights.axis @ lights.axis[0]) * side > 0.0
        if facing.any():
            np.testing.assert_allclose(lights.intensity[facing, 0].sum() / lights.emitters[0].radiance[0], area,
                                       rtol=1e-12)


def _reference(make):
    o = np.array(NEAR["position"])
    dirs = twin.camera_rays(o, NEAR["look_at"], [0.0, 1.0, 0.0], NEAR["fov"], NEAR["width"], NEAR["height"])
    return np.array([[twin.radiance(make(), o, d, KT, KS) for d in row] for row in dirs])


QUAD_TWIN = lambda: twin.Quad(QUAD["corners"], 10.0, exact=True)  # noqa: E731
# the emissive pair of the images: QUAD's corners as two triangles (the twin's parallelogram)
KINDS = {"quad": (QUAD, None, QUAD_TWIN),
         "disk": (DISK, None, lambda: twin.Disk(DISK["center"], DISK["normal"], 0.5, 10.0, exact=True)),
         "emissive pair": (None, {**EMISSIVE, "vertices": QUAD["corners"]}, QUAD_TWIN)}


def _z(sc, ref, samples, seeds):
    out = []
    for seed in seeds:
        img = api.render(sc, "montecarlo", volumetric_shadows=False, samples=samples, seed=seed)
        out.append((img.array[..., 0] - ref) / np.sqrt(img.variance[..., 0]))
    return np.array(out)


@pytest.mark.parametrize("kind", [pytest.param(k, marks=pytest.mark.slow) if k == "disk" else k for k in KINDS])
def test_flat_emitters_in_fog_against_the_exact_twin(kind, monkeypatch):
    """montecarlo's draws on a flat emitter against its exact twin (the disk: `-m slow`, 30 s; its points'
    uniformity and density are checked in CI above)."""
    light, shape, make = KINDS[kind]
    sc = scene([light] if light else [], camera=NEAR, shapes=[shape] if shape else [])
    ref = _reference(make)
    z = _z(sc, ref, 256, range(4))
    sd = math.sqrt(2.0 / z.size)
    assert abs(np.mean(z ** 2) - 1.0) < 4.0 * sd and np.abs(z).max() < 4.5, (np.mean(z ** 2), np.abs(z).max())
    if kind == "emissive pair":  # the rows of the rule itself (what the method drew before) are biased here
        monkeypatch.setattr("raytrace.methods.montecarlo.flat_rows", lambda lights: np.zeros(len(lights), bool))
        rows = _z(sc, ref, 256, range(2))
        assert np.mean(rows ** 2) > 5.0, np.mean(rows ** 2)


def test_the_same_image_on_any_thread_count():
    sc = scene([QUAD, {"type": "point", "position": [0.5, 0.5, 0.5], "intensity": 3.0}], camera={**NEAR, "width": 8,
                                                                                              "height": 6})
    one = api.render(sc, "montecarlo", volumetric_shadows=True, samples=8, seed=2, threads=1)
    two = api.render(sc, "montecarlo", volumetric_shadows=True, samples=8, seed=2, threads=2)
    np.testing.assert_array_equal(one.array, two.array)
    np.testing.assert_array_equal(one.variance, two.variance)


# away from the emitter (rays 0.4 or more below the quad) its rows converge: quadrature's image is the reference
FAR = {"position": [0.0, 0.0, 4.0], "look_at": [0.0, 0.0, 0.0], "fov": 30.0, "width": 4, "height": 3}
HEIGHT_FOG = {"type": "height_fog", "sigma_a": 0.03, "sigma_s": 0.25, "h0": 0.5, "scale_height": 1.5,
              "up": [0.0, 1.0, 0.0], "phase": {"type": "hg", "g": 0.6}}
PLANET = {"type": "atmosphere", "center": [0.0, -1000.0, 0.0], "radius": 1000.0, "top_radius": 1075.0,
          "reflectance": 0.0,
          "layer": [{"name": "rayleigh", "sigma_s": [0.046, 0.108, 0.265], "scale_height": 10.0, "phase": "rayleigh"},
                    {"name": "mie", "sigma_s": 0.032, "sigma_a": 0.0036, "scale_height": 1.5,
                     "phase": {"type": "hg", "g": 0.76}}]}


@pytest.mark.slow
@pytest.mark.parametrize("medium", [HEIGHT_FOG, PLANET], ids=["height fog", "atmosphere"])
def test_draws_in_a_height_fog_and_an_atmosphere_against_quadrature(medium):
    """The light moved to each drawn point in the other media's kernels (a height fog's light height, an
    atmosphere's light position): montecarlo (MIS: both strategies) against quadrature's converged rows
    by z-scores over 2 seeds at 256 samples, every channel (`-m slow`, compiles both media's kernels)."""
    sc = scene([QUAD], medium=medium, camera=FAR)
    ref = api.render(sc, "quadrature", volumetric_shadows=False).array
    z = np.array([(img.array - ref) / np.sqrt(img.variance) for img in
                  (api.render(sc, "montecarlo", volumetric_shadows=False, samples=256, seed=seed, sampling="mis")
                   for seed in range(2))])
    sd = math.sqrt(2.0 / z.size)
    assert np.all(ref > 0.0) and abs(np.mean(z ** 2) - 1.0) < 4.0 * sd and np.abs(z).max() < 4.5, (
        np.mean(z ** 2), np.abs(z).max())
