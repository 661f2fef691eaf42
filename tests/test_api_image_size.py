"""One of width and height alone keeps the scene camera's aspect (rounded to the nearest integer,
halves up, at least 1 pixel), the same on the command line, in the API and in gallery; both given
are taken as given."""
from __future__ import annotations

from types import SimpleNamespace

import pytest

import raytrace
from raytrace.api import image_size
from raytrace.cli import main
from raytrace.output.film import read_exr

from .conftest import box_room

CAM = SimpleNamespace(width=480, height=320)  # stage's camera, 3:2


@pytest.mark.parametrize("width, height, size", [
    (160, None, (160, 107)),  # 106.67
    (None, 100, (150, 100)),
    (3, None, (3, 2)),  # 2.0
    (1, None, (1, 1)),  # 0.67 rounds to 1
    (None, 1, (2, 1)),  # 1.5: halves up
    (7, 5, (7, 5)),  # both: as given, whatever the aspect
    (None, None, (480, 320)),
])
def test_image_size(width, height, size):
    assert image_size(CAM, width, height) == size


def test_a_tall_camera_never_gives_zero():
    assert image_size(SimpleNamespace(width=1000, height=1), width=3) == (3, 1)


def test_the_api_keeps_the_aspect():
    scene = box_room()  # 8 x 6
    assert raytrace.render(scene, width=4, threads=1).array.shape == (3, 4, 3)
    assert raytrace.render(scene, height=9, threads=1).array.shape == (9, 12, 3)
    assert raytrace.render(scene, width=5, height=5, threads=1).array.shape == (5, 5, 3)


def test_the_cli_keeps_the_aspect(tmp_path, capsys):
    out = tmp_path / "s.exr"
    assert main(["render", "stage", "--width", "16", "--spp", "1", "--threads", "1", "--out", str(out)]) == 0
    assert read_exr(out)[0].shape == (11, 16, 3)  # 480 x 320: 10.67 rows
    assert capsys.readouterr().out.startswith("stage: 16x11, ")
