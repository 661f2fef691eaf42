"""Keys a shape that holds a medium does not read are refused like any unread key (issue: the first
day): `reflectance` beside `interior` was accepted and ignored."""
import subprocess
import sys
from pathlib import Path

import pytest

import raytrace
from raytrace.errors import UserError

ROOT = Path(__file__).resolve().parents[1]
BOX = {"primitive": "box", "min": [-1, 0, -1], "max": [1, 1, 1], "interior": {"sigma_a": 0.1, "sigma_s": 0.2}}
SCENE = {"camera": {"position": [0, 0.5, 4], "look_at": [0, 0.5, 0], "width": 8, "height": 6},
         "light": [{"position": [0, 3, 0], "intensity": 5.0}], "medium": {"sigma_a": 0.0, "sigma_s": 0.0}}


def test_reflectance_on_a_shape_with_a_medium_is_refused():
    with pytest.raises(UserError, match=r"shape\[0\]\.reflectance: is not read on a shape that holds a medium.*remove"):
        raytrace.render(SCENE | {"shape": [BOX | {"reflectance": 0.5}]}, method="quadrature")
    raytrace.render(SCENE | {"shape": [BOX]}, method="quadrature", width=2, height=2)  # without it: renders


def test_the_command_line_says_it_in_one_line(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text('[camera]\nposition = [0, 0.5, 4]\nlook_at = [0, 0.5, 0]\nwidth = 8\nheight = 6\n'
                     '[[shape]]\nprimitive = "box"\nmin = [-1, 0, -1]\nmax = [1, 1, 1]\nreflectance = 0.5\n'
                     'interior = { sigma_a = 0.1, sigma_s = 0.2 }\n[[light]]\nposition = [0, 3, 0]\nintensity = 5.0\n')
    out = tmp_path / "o.exr"
    res = subprocess.run([sys.executable, str(ROOT / "render.py"), "render", str(scene), "--out", str(out)],
                         capture_output=True, text=True, cwd=tmp_path)
    assert res.returncode == 2
    assert res.stderr.strip().count("\n") == 0 and "shape[0].reflectance" in res.stderr
    assert not out.exists()
