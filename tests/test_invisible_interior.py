"""An index-matched shape whose interior is the outside medium itself changes nothing: the image of a
fog box crossed by the camera's rays equals the image without the box. A law of the whole crossing
(interiors/crossing.py: the rows inside, the rays leaving the box from its faces, the light's path
through it), checked against the renderer without the box, which takes none of that code."""
import numpy as np
import pytest

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from .conftest import to_toml

MEDIUM = {"sigma_a": [0.02, 0.03, 0.01], "sigma_s": [0.05, 0.04, 0.08]}
CAMERA = {"position": [0.5, 0.8, 4.0], "look_at": [0.0, 0.0, 0.0], "fov": 45.0, "width": 6, "height": 4, "spp": 1}
LIGHTS = {"lamp": {"position": [0.3, 1.6, -0.2], "intensity": [5.0, 4.0, 3.0]},
          "spot": {"type": "spot", "position": [1.5, 1.8, 0.5], "look_at": [0.0, 0.0, 0.0], "intensity": 6.0,
                   "cone_angle": 25.0, "falloff_start": 15.0}}
FLOOR = {"primitive": "quad", "corners": [[-3.0, -1.5, 3.0], [3.0, -1.5, 3.0], [3.0, -1.5, -3.0], [-3.0, -1.5, -3.0]],
         "reflectance": 0.5}
BOX = {"primitive": "box", "min": [-1.0, -1.0, -1.0], "max": [1.0, 1.0, 1.0], "interior": MEDIUM}


def image(light, shapes, shadows):
    scene = {"name": "invisible", "camera": CAMERA, "medium": MEDIUM, "shape": shapes, "light": [light]}
    return render(prepare(scene_from_text(to_toml(scene), "invisible")), "quadrature", {"rtol": 1e-11},
                  RenderOptions(threads=1, volumetric_shadows=shadows))


@pytest.mark.parametrize("shadows", [False, True], ids=["unshadowed", "shadowed"])
@pytest.mark.parametrize("light", list(LIGHTS))
def test_a_box_of_the_outside_medium_changes_nothing(light, shadows):
    """Every pixel within 1e-9 of the image without the box (the rays that cross the box and those
    that miss it, the floor seen through it and beside it; black where the spot does not reach), and
    inside the render's error bound where that is finite."""
    ref = image(LIGHTS[light], [FLOOR], shadows).image
    res = image(LIGHTS[light], [BOX, FLOOR], shadows)
    err = np.abs(res.image - ref)
    assert np.count_nonzero(ref[..., 1] > 0.0) >= 12
    assert np.all(err <= 1e-9 * ref), np.max(err / np.maximum(ref, 1e-300))
    finite = np.isfinite(res.error_bound)
    assert finite.any() and np.all(err[finite] <= res.error_bound[finite])
