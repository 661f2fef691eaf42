"""`--volumetric-shadows` / `--no-volumetric-shadows` and `volumetric_shadows=` in the API: on by
default, and a scene's [render] table (the bundled `shafts` turns them on)."""
from __future__ import annotations

import numpy as np

import raytrace
from raytrace.cli import main
from raytrace.output import film

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


def test_shadows_are_on_by_default():
    """A scene without [render] volumetric_shadows (box_room: a crate under the lamp) renders as
    with volumetric_shadows=True; False gives the unshadowed air-light, a different image."""
    default = raytrace.render("box_room", **SMALL)
    on = raytrace.render("box_room", volumetric_shadows=True, **SMALL)
    off = raytrace.render("box_room", volumetric_shadows=False, **SMALL)
    assert default.volumetric_shadows and not off.volumetric_shadows
    np.testing.assert_array_equal(default.array, on.array)
    assert not np.array_equal(default.array, off.array)


def test_media_inside_shapes_are_shadowed_by_default():
    """Media inside shapes (wax) take volumetric shadows like any scene: on by default, with no note,
    the same image as when asked for; off when turned off."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        default = raytrace.render("wax", **SMALL)
    on = raytrace.render("wax", volumetric_shadows=True, **SMALL)
    asked = raytrace.render("wax", overrides=["render.volumetric_shadows=true"], **SMALL)
    off = raytrace.render("wax", volumetric_shadows=False, **SMALL)
    assert default.volumetric_shadows and not off.volumetric_shadows
    np.testing.assert_array_equal(default.array, on.array)
    np.testing.assert_array_equal(default.array, asked.array)
    assert default.stats["inside: lit pieces"] > 0 and "inside: lit pieces" not in off.stats


def test_the_cli_shadows_media_inside_shapes_and_the_flag_turns_them_off(tmp_path):
    args = ["--width", "6", "--height", "4", "--threads", "1", "--quiet"]
    assert main(["wax", "--out", str(tmp_path / "a.exr"), *args]) == 0
    assert film.read_exr(tmp_path / "a.exr")[1]["volumetric_shadows"] == "true"
    assert main(["wax", "--no-volumetric-shadows", "--out", str(tmp_path / "b.exr"), *args]) == 0
    assert film.read_exr(tmp_path / "b.exr")[1]["volumetric_shadows"] == "false"


def test_table1_starts_unshadowed(tmp_path, monkeypatch):
    """The paper's Table 1 is unshadowed: the command gives table1.run options without shadows."""
    from raytrace.experiments import table1

    seen = []
    monkeypatch.setattr(table1, "run", lambda out, quick, options, **kw: seen.append(options))
    assert main(["table1", "--out", str(tmp_path), "--quick"]) == 0
    assert len(seen) == 1 and seen[0].volumetric_shadows is False
