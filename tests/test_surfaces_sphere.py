"""Plain surfaces inside a refractive exact sphere lit by point and spot lights (interiors/surfaces.py
`_lit_into_sphere`, `_into_sphere`: the air-light's refracted paths, media/sphere_refraction.py) against the twin
of tests/make_surfaces_sphere_twins.py (30-digit mpmath from the geometry alone; its docstring says how): a glass
ball (ior 1.5) sunk into a floor, with a plate inside it and one outside between it and the light, under a lamp and
a spot; an absorbing interior and outside medium that do not scatter, so that a pixel that sees a surface inside
holds that surface's term alone.
Before: the floor inside the ball was black under these lights (a shape whose first vertex lay inside the ball was
refused: "surfaces inside it are lit by directional lights only").
"""
import json

import numpy as np
import pytest

from raytrace.interiors.surfaces import _into_sphere
from raytrace.media.sphere_refraction import MAX_PATHS
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import make_surfaces_sphere_twins as twin
from .conftest import to_toml

TWIN = json.loads(twin.PATH.read_text())


def scene(light):
    sc = {"camera": twin.VIEW, "light": [light], "medium": {"sigma_a": twin.KT_OUT},
          "shape": [{"primitive": "sphere", "center": twin.CENTRE, "radius": twin.RADIUS, "exact": True,
                     "interior": {"sigma_a": twin.KT, "sigma_s": 0.0, "ior": twin.ETA}}]
          + [{"primitive": "quad", "corners": q, "reflectance": twin.RHO} for q in twin.QUADS]}
    return prepare(scene_from_text(to_toml(sc), "ball_on_floor"))


def paths_at(light, points):
    """`_into_sphere`'s (value, inside, outside, toward) of the light (a unit one) at the points, one row per point."""
    rows = scene(light).lights
    m = len(points)
    value, inside, outside = np.zeros((m, MAX_PATHS)), np.zeros((m, MAX_PATHS)), np.zeros((m, MAX_PATHS))
    toward, boundary = np.zeros((m, MAX_PATHS, 3)), np.zeros((m, MAX_PATHS, 3))
    _into_sphere(np.array(points, float), np.array([*twin.CENTRE, twin.RADIUS]), rows.position[0], rows.axis[0],
                 rows.cone[0], twin.ETA, value, toward, inside, outside, boundary)
    return value, inside, outside, toward


@pytest.mark.parametrize("name", sorted(twin.LIGHTS))
def test_the_paths_match_the_twin(name):
    """Every path the twin finds at the points (one or two; none beyond the marginal rays) found, and no other:
    the irradiance with the spot's falloff, both legs and the direction within 1e-10 (measured below 1e-13); the
    first point's paths recomputed live."""
    light = twin.LIGHTS[name]
    value, inside, outside, toward = paths_at(light, twin.POINTS)
    live = [[float(x) for x in (ef, s, o, *t)] for ef, s, o, t, _ in twin.paths(twin.vec(twin.POINTS[0]), light)]
    assert np.allclose(live, np.array(TWIN["points"][name][0], float), rtol=1e-20, atol=1e-24)
    counts = set()
    for i, ref in enumerate(TWIN["points"][name]):
        ref = np.array(ref, float).reshape(-1, 6)
        ref = ref[ref[:, 0] > 0.0]
        got = np.nonzero(value[i] > 0.0)[0]
        assert len(got) == len(ref), (i, value[i], ref)
        counts.add(len(ref))
        for k in got:
            j = int(np.argmin(np.linalg.norm(ref[:, 3:] + toward[i, k], axis=1)))  # toward: back along t
            assert np.allclose(toward[i, k], -ref[j, 3:], rtol=0.0, atol=1e-10), (i, k)
            for a, b in ((value[i, k], ref[j, 0]), (inside[i, k], ref[j, 1]), (outside[i, k], ref[j, 2])):
                assert abs(a / b - 1.0) <= 1e-10, (i, k, a, b)
    assert counts == {0, 1, 2}, counts


@pytest.mark.parametrize("name", sorted(twin.LIGHTS))
def test_the_floor_and_plate_inside_match_the_twin(name):
    """Every pixel whose ray enters the ball and first meets the floor or the plate inside (its mirror image
    meeting no quad) within 1e-10 of the twin (measured below 1e-13), lit pixels and dark ones (shadowed by the
    plates, beyond the marginal rays, outside the spot's cone) among them; the same image for raymarch (nothing
    scatters)."""
    prep = scene(twin.LIGHTS[name])
    img = render(prep, "quadrature", {}, RenderOptions(threads=1)).image
    lit = 0
    for i, j, ref in TWIN["pixels"][name]:
        ref = np.array(ref, float)
        lit += bool(np.all(ref > 0.0))
        assert np.allclose(img[j, i], ref, rtol=1e-10, atol=1e-300), (i, j, img[j, i], ref)
    seen = len(TWIN["pixels"][name])
    assert seen >= 40 and lit >= 15 and seen - lit >= 20, (seen, lit)
    assert np.array_equal(render(prep, "raymarch", {"steps": 4}, RenderOptions(threads=1)).image, img)
