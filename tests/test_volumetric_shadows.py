"""Volumetric shadows (`--volumetric-shadows`) for every method that exposes its medium points."""
import numpy as np
import pytest

from raytrace.methods import registry
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from .conftest import box_room, to_toml

METHODS = [name for name, m in registry().items() if m.points is not None]
CAMERA = {"position": [0.0, 0.0, 3.5], "look_at": [0.0, 0.0, -1.0], "fov": 80.0, "width": 16, "height": 12, "spp": 1}
LIGHT = [{"position": [0.0, 1.5, -1.0], "intensity": 20.0}]


def prep(shapes):
    s = box_room(camera=CAMERA, light=LIGHT, medium={"sigma_a": 0.02, "sigma_s": [0.2, 0.3, 0.4]})
    s["shape"] = s["shape"] + shapes
    return prepare(scene_from_text(to_toml(s), "test"))


def test_some_methods_support_volumetric_shadows():
    assert "montecarlo" in METHODS


@pytest.mark.parametrize("method", METHODS)
def test_without_occluders_equals_the_unshadowed_result(method):
    p = prep([])
    a = render(p, method, {}, RenderOptions(seed=3, threads=1)).image
    b = render(p, method, {}, RenderOptions(seed=3, threads=1, volumetric_shadows=True)).image
    np.testing.assert_allclose(b, a, rtol=1e-9)


@pytest.mark.parametrize("method", METHODS)
def test_an_occluder_casts_a_shadow_into_the_fog(method):
    """A horizontal plate just below the light shadows the whole lower half of the room's fog:
    rays looking down see much less air-light than without volumetric shadows."""
    plate = {"primitive": "quad", "corners": [[-2.9, 1.2, -3.9], [2.9, 1.2, -3.9], [2.9, 1.2, 3.9], [-2.9, 1.2, 3.9]],
             "reflectance": 0.0}
    p = prep([plate])
    params = {"samples": 16} if method == "montecarlo" else {}
    a = render(p, method, params, RenderOptions(seed=3, threads=1)).image
    b = render(p, method, params, RenderOptions(seed=3, threads=1, volumetric_shadows=True)).image
    lower = slice(8, 12)  # image rows looking down, whose rays stay below the plate
    assert np.all(b[lower] < 0.25 * a[lower])
    assert np.all(b <= a * (1 + 1e-12))
