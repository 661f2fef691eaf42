"""`--volumetric-shadows` / `--no-volumetric-shadows` and `volumetric_shadows=` in the API against a
scene whose [render] table turns shadows on (the bundled `shafts`)."""
from __future__ import annotations

import numpy as np

import raytrace
from raytrace import film
from raytrace.cli import main

SMALL = dict(width=6, height=4, threads=1)


def test_the_api_turns_a_scenes_shadows_off():
    on = raytrace.render("shafts", **SMALL)
    off = raytrace.render("shafts", volumetric_shadows=False, **SMALL)
    unshadowed = raytrace.render("shafts", overrides=["render.volumetric_shadows=false"], **SMALL)
    assert on.volumetric_shadows and not off.volumetric_shadows
    np.testing.assert_array_equal(off.array, unshadowed.array)
    assert not np.array_equal(on.array, off.array)  # the columns' shadows change the image


def test_the_flags_override_the_scene_both_ways(tmp_path):
    args = ["--width", "6", "--height", "4", "--threads", "1", "--quiet"]
    for flag, want in (("--no-volumetric-shadows", "false"), ("--volumetric-shadows", "true")):
        out = tmp_path / f"{flag}.exr"
        assert main(["shafts", flag, "--out", str(out), *args]) == 0
        assert film.read_exr(out)[1]["volumetric_shadows"] == want
    out = tmp_path / "scene.exr"
    assert main(["shafts", "--out", str(out), *args]) == 0  # neither flag: the scene's [render] value
    assert film.read_exr(out)[1]["volumetric_shadows"] == "true"
