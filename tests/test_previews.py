"""PNG previews through the view (raytrace/output/view.py) from the API and the command line: the neutral view
(Khronos PBR Neutral) by default, ACES 2.0 as "aces", the plain sRGB encode as "standard", exposure checked
before anything is written."""
from __future__ import annotations

import math
import os

import numpy as np
import pytest
from PIL import Image as PILImage

import raytrace
from raytrace.cli import main
from raytrace.output import film, view

from .conftest import box_room, to_toml


def _png(path):
    with PILImage.open(path) as im:
        return np.asarray(im.convert("RGB"))


@pytest.fixture(scope="module")
def img():
    return raytrace.render(box_room(), method="analytic", width=8, height=6, threads=1)


def test_save_png_goes_through_the_view(tmp_path, img):
    img.save(tmp_path / "a.png")
    np.testing.assert_array_equal(_png(tmp_path / "a.png"), view.to_display(img.array, None, "neutral"))
    img.save(tmp_path / "b.png", exposure=-1.5)
    np.testing.assert_array_equal(_png(tmp_path / "b.png"), view.to_display(img.array, -1.5, "neutral"))
    img.save(tmp_path / "d.png", view="aces")
    np.testing.assert_array_equal(_png(tmp_path / "d.png"), view.to_display(img.array, None, "aces"))
    img.save(tmp_path / "c.png", exposure=0.0, view="standard")
    np.testing.assert_array_equal(_png(tmp_path / "c.png"), film.srgb_encode(img.array, 0.0))


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, "bright"])
def test_save_refuses_a_non_finite_exposure_naming_it(tmp_path, img, bad):
    with pytest.raises(raytrace.UserError, match=r"^exposure: .*not a finite number of stops"):
        img.save(tmp_path / "a.png", exposure=bad)
    assert os.listdir(tmp_path) == []


def test_save_refuses_an_unknown_view(tmp_path, img):
    with pytest.raises(raytrace.UserError, match=r"^view: unknown view 'filmic'; choose one of: neutral, aces, standard"):
        img.save(tmp_path / "a.png", view="filmic")


def _scene(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(to_toml(box_room()))
    return str(path)


def test_cli_png_views(tmp_path):
    scene = _scene(tmp_path)
    for name, extra in (("neutral", []), ("aces", ["--view", "aces"]),
                        ("standard", ["--view", "standard", "--exposure", "1"])):
        out, png = tmp_path / f"{name}.exr", tmp_path / f"{name}.png"
        assert main([scene, "--width", "8", "--height", "6", "--out", str(out), "--png", str(png), "--quiet",
                     *extra]) == 0
        array, _ = film.read_exr(out)
        want = view.to_display(array, None, name) if name != "standard" else film.srgb_encode(array, 1.0)
        # the PNG is made from the float64 image, the EXR holds float32: allow one code of rounding
        assert np.abs(_png(png).astype(int) - want).max() <= 1


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_cli_refuses_a_non_finite_exposure_before_rendering(tmp_path, capsys, value):
    out = tmp_path / "a.exr"
    assert main([_scene(tmp_path), "--out", str(out), "--png", str(tmp_path / "a.png"), f"--exposure={value}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: --exposure: ") and "finite number of stops" in err
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]


def test_compare_refuses_a_non_finite_exposure(tmp_path, capsys):
    assert main(["compare", _scene(tmp_path), "--methods", "analytic", "--out", str(tmp_path / "c"),
                 "--exposure", "nan"]) == 2
    assert "--exposure" in capsys.readouterr().err and not (tmp_path / "c").exists()


@pytest.mark.parametrize("scene", [None, "ocean"])
def test_bundled_scene_previews_from_the_cli_clip_at_most_two_percent(tmp_path, scene):
    """The PNG `render` writes for the default scene and the ocean: at most 2 % of the pixels at 255
    in any channel (the plain sRGB encode of the ocean clipped about half of them)."""
    out, png = tmp_path / "a.exr", tmp_path / "a.png"
    args = ([scene] if scene else []) + ["--width", "96", "--height", "54", "--threads", "1",
                                         "--out", str(out), "--png", str(png), "--quiet"]
    assert main(args) == 0
    rgb = _png(png)
    assert max(float(np.mean(rgb[..., c] == 255)) for c in range(3)) <= 0.02
