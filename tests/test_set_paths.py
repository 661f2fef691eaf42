"""--set key paths: one canonical spelling with array entries in brackets (`light[1].intensity`,
the spelling of the parser's error messages), and the dotted spelling (`light.1.intensity`) read the same."""
from __future__ import annotations

import numpy as np
import pytest

import raytrace
from raytrace.scene.format import parse_override

from .conftest import box_room

TWO_LIGHTS = box_room(light=[{"position": [0.0, 2.0, -1.0], "intensity": 10.0},
                             {"position": [1.0, 2.0, -3.0], "intensity": 5.0}])


@pytest.mark.parametrize("text, key", [("light[1].intensity=2", "light[1].intensity"),
                                       ("light.1.intensity=2", "light[1].intensity"),
                                       ("camera.position.1=2", "camera.position[1]"),
                                       ("camera.position[1]=2", "camera.position[1]"),
                                       ("shape[0].transform.translate[2]=2", "shape[0].transform.translate[2]"),
                                       (" medium.sigma_s =2", "medium.sigma_s")])
def test_both_spellings_give_the_canonical_key(text, key):
    assert parse_override(text, "s") == (key, 2)


def test_both_spellings_set_the_same_value():
    a = raytrace.load(TWO_LIGHTS, ["light[1].intensity=[1, 2, 3]", "camera.position[1]=1.25"])
    b = raytrace.load(TWO_LIGHTS, ["light.1.intensity=[1, 2, 3]", "camera.position.1=1.25"])
    for s in (a, b):
        np.testing.assert_array_equal(s.lights[1].intensity, [1.0, 2.0, 3.0])
        np.testing.assert_array_equal(s.lights[0].intensity, [10.0, 10.0, 10.0])
        assert s.camera.position[1] == 1.25


def test_errors_name_the_key_as_the_parser_does():
    """The override's error and the parser's error for the value it set write the same path."""
    with pytest.raises(raytrace.UserError, match=r"--set light\[2\]\.intensity: light has 2 entries; index them "
                                                 r"0\.\.1, e\.g\. light\[0\]"):
        raytrace.load(TWO_LIGHTS, ["light.2.intensity=1"])
    with pytest.raises(raytrace.UserError, match=r"light\[1\]\.intensity"):
        raytrace.load(TWO_LIGHTS, ["light.1.intensity=-1"])
