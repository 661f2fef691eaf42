"""A spot's refracted paths into the 512-plane glass UV ball (32 segments), its beam's edge across the
ball: the cone levels' crossings along a refracted path (media/slab.py `refracted_cuts`, `_cone_crossings`)
and the edges where a refraction point leaves its face, with the bound `quadrature` reports there.

The twin uses the geometry alone: tests/test_refracted_mesh_faces.py's (each triangle's Fermat path in the
plane of incidence, counted where the refraction point lies in the triangle, the ray tube's irradiance,
the spot's smoothstep falloff of the direction the light leaves in; scipy quad cut where the triangle's
lit set or either cone level's side changes, each bisected on its indicator). Slow (the twin's
Fermat paths over the ball's triangles, about a minute a pixel): `python -m pytest -m slow
tests/test_refracted_uv_ball_spot.py`.
"""
import numpy as np
import pytest

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from .conftest import to_toml
from .test_refracted_mesh_faces import twin_pixel
from .test_refracted_uv_ball_sun import uv_ball, uv_triangles

SPOT = {"type": "spot", "position": [2.0, 2.0, 1.0], "look_at": [0.0, 0.0, 0.0], "intensity": 5.0,
        "cone_angle": 12.0, "falloff_start": 6.0}
SCENE = uv_ball(32, 32, 24) | {"medium": {"sigma_a": 0.02}, "light": [SPOT]}
PIXELS = [(17, 1), (16, 2), (25, 12), (24, 14), (21, 5)]


@pytest.mark.slow
def test_the_spot_into_the_512_plane_ball_against_the_twin():
    """Pixels across the beam's edge (two at the top of the ball where the cone levels cross refracted
    paths at a glance, two dim ones at its side) and one in the beam, rendered alone with `quadrature` at
    rtol 1e-6: within 1e-6 of the twin, every bound finite and above the error, the median bound at
    most 10 rtol of the value."""
    geometry = uv_triangles(SCENE)[:3]
    prep = prepare(scene_from_text(to_toml(SCENE), SCENE["name"]))
    ratios = []
    for i, j in PIXELS:
        ref = twin_pixel(SCENE, geometry, i, j)[0]
        res = render(prep, "quadrature", {"rtol": 1e-6}, RenderOptions(threads=1, crop=(i, j, i + 1, j + 1)))
        value, bound = res.image.reshape(-1, 3)[-1], res.error_bound.reshape(-1, 3)[-1]
        err = np.abs(value - ref)
        assert np.all(ref > 0.0)
        assert np.all(np.isfinite(bound)) and np.all(err <= bound), ((i, j), err, bound)
        assert np.all(err <= 1e-6 * ref), ((i, j), err / ref)
        ratios.append(bound / ref)
    assert np.median(ratios) <= 1e-5, ratios
