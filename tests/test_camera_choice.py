"""`--camera NAME` / `camera="NAME"`: the camera of a glTF file chosen by name through api.scene_dict and
raytrace.io; refused in one line for scenes with a single camera (TOML, dicts, the default scene) and for
formats whose importer does not choose by name."""
from __future__ import annotations

import pytest

import raytrace
from raytrace.cli import main

from .conftest import box_room, to_toml
from .test_io_gltf import write_gltf

CAMERAS = {"cameras": [{"name": "wide", "type": "perspective", "perspective": {"yfov": 0.5, "aspectRatio": 2.0}},
                       {"name": "square", "type": "perspective", "perspective": {"yfov": 1.0}}],
           "nodes": [{"camera": 0, "translation": [0, 1, 5]}, {"camera": 1, "name": "node-of-square",
                                                                "translation": [0, 0, 3]}]}


def test_load_and_describe_choose_the_named_camera(tmp_path, capsys):
    path = write_gltf(tmp_path, CAMERAS)
    first, square = raytrace.load(path).camera, raytrace.load(path, camera="node-of-square").camera
    assert (first.width, first.height, list(first.position)) == (1024, 512, [0, 1, 5])
    assert (square.width, square.height, list(square.position)) == (512, 512, [0, 0, 3])
    assert main(["describe", str(path), "--camera", "square"]) == 0
    assert "512x512" in capsys.readouterr().out


def test_render_takes_the_camera_keyword(tmp_path):
    path = write_gltf(tmp_path, CAMERAS)
    img = raytrace.render(path, camera="square", height=4, width=None, method="analytic")
    assert img.array.shape == (4, 4, 3)  # the square camera's aspect (the first, 1024 x 512, would give 4 x 8)


def test_an_unknown_name_lists_the_cameras(tmp_path, capsys):
    path = write_gltf(tmp_path, CAMERAS)
    assert main(["describe", str(path), "--camera", "nope"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no camera named 'nope'; choose one of: node-of-square, square, wide" in err


def test_a_scene_with_one_camera_refuses_a_name(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(to_toml(box_room()))
    for scene in (str(path), None, box_room()):
        with pytest.raises(raytrace.UserError, match=r"camera='front' \(--camera on the command line\): names a "
                                                     r"camera of a glTF file; .*--set camera\.position"):
            raytrace.load(scene, camera="front")
    assert main(["render", str(path), "--camera", "front", "--out", str(tmp_path / "a.exr")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"error: {path}: camera='front'")
    assert not (tmp_path / "a.exr").exists()


def test_a_format_that_does_not_choose_by_name_refuses_it(tmp_path):
    path = tmp_path / "s.xml"
    path.write_text('<scene version="3.0.0"/>')
    with pytest.raises(raytrace.UserError, match=r"s\.xml: camera 'front' \(--camera\): this format's importer "
                                                 r"reads one camera"):
        raytrace.load(path, camera="front")
