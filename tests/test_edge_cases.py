"""Closed-form scenes and geometric edge cases of whole renders (SCENE_FORMAT.md radiance model)."""
import math

import numpy as np
import pytest

from raytrace.cli import main
from raytrace.output.film import read_exr

from .conftest import box_room


def render(write_scene, tmp_path, scene, *extra, name="img.exr"):
    path = write_scene(scene, name.replace(".exr", ".toml"))
    out = tmp_path / name
    assert main(["render", str(path), "--out", str(out), "--quiet", *extra]) == 0
    return read_exr(out)[0]


def test_pure_absorption_is_exp_times_surface_term(write_scene, tmp_path):
    """Light at the camera, centre pixel looking straight at a wall at distance t:
    L = rho/pi I exp(-ka t) exp(-ka t) / t^2 exactly (cos = 1, d = t)."""
    ka = np.array([0.1, 0.25, 0.5])
    scene = box_room(camera={"position": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, -1.0], "width": 1, "height": 1},
                     light=[{"position": [0.0, 0.0, 0.0], "intensity": [10.0, 20.0, 30.0]}],
                     medium={"sigma_a": ka.tolist(), "sigma_s": 0.0})
    img = render(write_scene, tmp_path, scene, "--method", "quadrature")
    t = 4.0
    expected = np.array([0.6, 0.5, 0.4]) / math.pi * np.array([10.0, 20.0, 30.0]) * np.exp(-2 * ka * t) / t**2
    np.testing.assert_allclose(img[0, 0], expected, rtol=1e-6)


def test_vacuum_with_background_and_rays_that_hit_nothing(write_scene, tmp_path):
    """No shapes: every ray misses; vacuum channels show the background, absorbing ones nothing."""
    scene = {"camera": {"type": "environment", "position": [0, 0, 0], "look_at": [0, 0, -1], "width": 8, "height": 4},
             "light": [{"position": [0.0, 1.0, -2.0], "intensity": 5.0}],
             "medium": {"sigma_a": [0.0, 0.1, 0.0], "sigma_s": [0.0, 0.0, 0.2]},
             "background": {"radiance": [0.25, 0.5, 0.75]}}
    img = render(write_scene, tmp_path, scene, "--method", "quadrature")
    assert np.all(np.isfinite(img))
    np.testing.assert_allclose(img[..., 0], 0.25, rtol=1e-7)
    np.testing.assert_allclose(img[..., 1], 0.0, atol=0)
    assert np.all(img[..., 2] > 0)  # air-light only: the background is fully extinguished at t = inf


def test_ray_through_a_light_is_finite(write_scene, tmp_path):
    scene = box_room(camera={"position": [0.0, 0.0, 3.0], "look_at": [0.0, 0.0, -1.0], "width": 1, "height": 1},
                     light=[{"position": [0.0, 0.0, -1.0], "intensity": 1.0}])
    img = render(write_scene, tmp_path, scene, "--method", "quadrature")
    assert np.all(np.isfinite(img)) and np.all(img > 0)


def test_light_on_a_surface_and_behind_the_camera(write_scene, tmp_path):
    scene = box_room(light=[{"position": [0.0, 0.0, -4.0], "intensity": 3.0},    # on the far wall
                            {"position": [0.3, 0.2, 3.9], "intensity": 3.0}])    # behind the camera
    img = render(write_scene, tmp_path, scene, "--method", "quadrature")
    assert np.all(np.isfinite(img)) and np.all(img >= 0)


def test_result_does_not_depend_on_thread_count(write_scene, tmp_path):
    scene = box_room(camera={"position": [0.3, 0.2, 3.0], "look_at": [0.0, 0.0, -1.0], "width": 64, "height": 300,
                             "spp": 4})
    one = render(write_scene, tmp_path, scene, "--method", "quadrature", "--threads", "1", name="a.exr")
    two = render(write_scene, tmp_path, scene, "--method", "quadrature", "--threads", "2", name="b.exr")
    assert np.array_equal(one, two)


def test_camera_on_a_light_is_finite_for_every_method(write_scene, tmp_path):
    """Every ray starts at the light: the true air-light of a point light is infinite; the light is
    regularised as a sphere of 1e-9 times the scene's size, so every method gives finite pixels,
    and the closed form agrees with the quadrature."""
    from raytrace.methods import registry

    scene = box_room(camera={"position": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, -1.0], "width": 4, "height": 3},
                     light=[{"position": [0.0, 0.0, 0.0], "intensity": 5.0}])
    images = {m: render(write_scene, tmp_path, scene, "--method", m, name=f"{m}.exr") for m in registry()}
    for m, img in images.items():
        assert np.all(np.isfinite(img)), m
    np.testing.assert_allclose(images["analytic"], images["quadrature"], rtol=1e-3)


@pytest.mark.parametrize("method", ["analytic", "montecarlo"])
def test_crop_equals_the_block_of_the_whole_image(write_scene, tmp_path, method):
    scene = box_room(camera={"position": [0.3, 0.2, 3.0], "look_at": [0.0, 0.0, -1.0], "width": 12, "height": 9,
                             "spp": 4})
    whole = render(write_scene, tmp_path, scene, "--method", method, name="whole.exr")
    part = render(write_scene, tmp_path, scene, "--method", method, "--crop", "3,2,7,5", name="part.exr")
    assert part.shape == (3, 4, 3)
    np.testing.assert_array_equal(part, whole[2:5, 3:7])
