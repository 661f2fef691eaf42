"""Image files (output/film.py), tone mapping, error-map colours and the `diff` command's numbers."""
from __future__ import annotations

import os

import numpy as np
import pytest

from raytrace.cli import main
from raytrace.errors import UserError
from raytrace.output import film, metrics


def srgb8(x):
    """The sRGB transfer function (IEC 61966-2-1) to 8 bits, written out independently of output/film.py."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    v = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    return np.floor(v * 255 + 0.5).astype(int)


# --- EXR ---------------------------------------------------------------------------------------------------

def test_exr_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(1)
    img = (rng.standard_normal((5, 7, 3)) * 10.0 ** rng.uniform(-30, 30, (5, 7, 3))).astype(np.float32)
    img[0, 0] = [0.0, -0.0, np.float32(1e-40)]  # zero, negative zero, a float32 denormal
    img[0, 1] = [np.finfo(np.float32).max, np.finfo(np.float32).tiny, 1.0 + np.finfo(np.float32).eps]
    p = tmp_path / "img.exr"
    film.write_exr(p, img, {"method": "quadrature", "spp": 16, "seed": 7, "note": "two words", "x": 0.125})
    back, header = film.read_exr(p)
    assert back.shape == (5, 7, 3) and back.dtype == np.float64
    np.testing.assert_array_equal(back, img.astype(np.float64))
    assert header["method"] == "quadrature"
    assert header["spp"] == "16" and header["seed"] == "7"
    assert header["note"] == "two words" and float(header["x"]) == 0.125
    assert os.listdir(tmp_path) == ["img.exr"]  # no temporary files


def test_exr_is_float32_rgb_and_has_extra_channels(tmp_path):
    import OpenEXR

    img = np.arange(2 * 3 * 3, dtype=np.float64).reshape(2, 3, 3) / 7.0
    var = np.full((2, 3), 0.25)
    p = tmp_path / "img.exr"
    film.write_exr(p, img, extra={"variance.R": var})
    with OpenEXR.File(str(p), separate_channels=True) as f:
        ch = f.channels()
        assert {"R", "G", "B", "variance.R"} <= set(ch)
        for c in "RGB":
            assert ch[c].pixels.dtype == np.float32
        np.testing.assert_array_equal(ch["G"].pixels, img[..., 1].astype(np.float32))
        np.testing.assert_array_equal(ch["variance.R"].pixels, np.float32(0.25))


def test_exr_overwrite_replaces(tmp_path):
    p = tmp_path / "img.exr"
    film.write_exr(p, np.zeros((2, 2, 3)))
    film.write_exr(p, np.ones((3, 1, 3)))
    back, _ = film.read_exr(p)
    np.testing.assert_array_equal(back, np.ones((3, 1, 3)))
    assert os.listdir(tmp_path) == ["img.exr"]


def test_exr_write_into_missing_folder(tmp_path):
    with pytest.raises(UserError, match="does not exist"):
        film.write_exr(tmp_path / "nope" / "a.exr", np.zeros((1, 1, 3)))
    assert os.listdir(tmp_path) == []


def test_failed_write_leaves_nothing(tmp_path):
    def boom(tmp):
        with open(tmp, "wb") as f:
            f.write(b"partial")
        raise OSError(28, "No space left on device")

    with pytest.raises(UserError, match="No space left"):
        film._atomic_write(tmp_path / "a.exr", boom)
    assert os.listdir(tmp_path) == []


def test_read_exr_errors(tmp_path):
    with pytest.raises(UserError, match="no such image"):
        film.read_exr(tmp_path / "missing.exr")
    bad = tmp_path / "bad.exr"
    bad.write_bytes(b"\x76\x2f\x31\x01 but not really")
    with pytest.raises(UserError, match="not a readable"):
        film.read_exr(bad)


def test_render_writes_exr_header_and_png(tmp_path, capsys):
    from .conftest import box_room, to_toml

    scene = tmp_path / "s.toml"
    scene.write_text(to_toml(box_room()))
    out, png = tmp_path / "out" / "r.exr", tmp_path / "out" / "r.png"
    out.parent.mkdir()
    method = "analytic"
    rc = main(["render", str(scene), "--method", method, "--spp", "4", "--seed", "11", "--width", "5",
               "--height", "3", "--out", str(out), "--png", str(png), "--quiet"])
    assert rc == 0
    assert capsys.readouterr().err == ""
    img, header = film.read_exr(out)
    assert img.shape == (3, 5, 3)
    assert np.all(np.isfinite(img)) and np.all(img >= 0.0) and img.max() > 0.0
    assert header["method"] == method and header["spp"] == "4" and header["seed"] == "11"
    assert header["scene"] == "s"
    assert float(header["render_seconds"]) >= 0.0
    from PIL import Image

    with Image.open(png) as im:
        assert im.size == (5, 3) and im.mode == "RGB"
        np.testing.assert_array_equal(np.asarray(im), film.tonemap(img.astype(np.float32)))
    assert sorted(os.listdir(out.parent)) == ["r.exr", "r.png"]


# --- PNG and tone mapping ----------------------------------------------------------------------------------

def test_png_size_and_pixels(tmp_path):
    from PIL import Image

    rgb = np.zeros((3, 5, 3), dtype=np.uint8)
    rgb[0, 4] = [255, 10, 0]
    rgb[2, 0] = [1, 2, 3]
    p = tmp_path / "a.png"
    film.write_png(p, rgb)
    with Image.open(p) as im:
        assert im.size == (5, 3)  # width x height
        np.testing.assert_array_equal(np.asarray(im.convert("RGB")), rgb)
    assert os.listdir(tmp_path) == ["a.png"]


@pytest.mark.parametrize("linear,expected", [
    (0.0, 0), (1.0, 255), (0.5, 188), (0.18, 118), (0.2158605, 128), (0.0031308, 10), (0.001, 3),
    (2.0, 255), (-1.0, 0),
])
def test_tonemap_srgb_anchor_values(linear, expected):
    """Well-known 8-bit sRGB codes: linear 0.5 → 188, mid grey 0.18 → 118, code 128 ↔ 0.2158605."""
    out = film.tonemap(np.full((1, 1, 3), linear), exposure=0.0, view="standard")
    assert out.dtype == np.uint8 and out.shape == (1, 1, 3)
    assert np.all(out == expected)


def test_tonemap_matches_srgb_everywhere():
    x = np.linspace(0.0, 1.0, 2001)
    img = np.stack([x, x[::-1], np.sqrt(x)], axis=-1)[None]
    out = film.tonemap(img, exposure=0.0, view="standard").astype(int)
    assert np.abs(out - srgb8(img)).max() <= 1  # rounding at code boundaries only
    assert np.mean(out == srgb8(img)) > 0.99


def test_tonemap_monotone_and_exposure():
    x = np.geomspace(1e-6, 50.0, 3000)
    img = np.repeat(x[None, :, None], 3, axis=2)
    for exposure in (-3.0, 0.0, 2.5):
        out = film.tonemap(img, exposure, "standard")[0, :, 0].astype(int)
        assert np.all(np.diff(out) >= 0)
    # one stop of exposure is a factor of two
    np.testing.assert_array_equal(film.tonemap(img * 2.0, 0.0, "standard"), film.tonemap(img, 1.0, "standard"))
    np.testing.assert_array_equal(film.tonemap(img, -2.0, "standard"), film.tonemap(img / 4.0, 0.0, "standard"))


def test_tonemap_auto_exposure_and_bad_pixels():
    grey = np.full((4, 4, 3), 0.3)
    assert np.all(film.tonemap(grey, view="standard") == 255)  # 99.5th percentile of luminance → 1
    img = np.zeros((10, 20, 3))
    img[..., :] = np.linspace(0.0, 4.0, 20)[None, :, None]
    out = film.tonemap(img, view="standard")
    # the 99.5th percentile of 0..4 in 20 steps is close to 4: the brightest column is (nearly) white
    p = np.percentile(img[..., 0], 99.5)
    np.testing.assert_array_equal(out[0, :, 0], srgb8(img[0, :, 0] / p))
    bad = np.array([[[np.nan, np.inf, -np.inf]]])
    np.testing.assert_array_equal(film.tonemap(bad, 0.0, "standard"), [[[0, 255, 0]]])
    black = film.tonemap(np.zeros((2, 2, 3)), view="standard")
    assert np.all(black == 0)


# --- error maps ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("value,rgb", [
    (0.0, (0, 0, 255)),      # blue
    (0.25, (0, 255, 255)),   # cyan
    (0.5, (0, 255, 0)),      # green
    (0.75, (255, 255, 0)),   # yellow
    (1.0, (255, 0, 0)),      # red
    (2.0, (255, 0, 0)),      # clipped at the top of the scale
])
def test_hue_map_anchors(value, rgb):
    out = metrics.hue_map(np.array([[value * 3.0]]), 3.0)
    np.testing.assert_array_equal(out[0, 0], rgb)


def test_hue_map_hue_decreases_monotonically():
    import colorsys

    v = np.linspace(0.0, 1.0, 501)
    out = metrics.hue_map(v, 1.0) / 255.0
    hsv = np.array([colorsys.rgb_to_hsv(*c) for c in out])
    np.testing.assert_allclose(hsv[:, 2], 1.0)  # full value
    np.testing.assert_allclose(hsv[:, 1], 1.0)  # full saturation
    hue_deg = hsv[:, 0] * 360.0
    np.testing.assert_allclose(hue_deg, 240.0 * (1.0 - v), atol=0.6)  # blue (240°) → red (0°), linear


def _exr(path, img):
    film.write_exr(path, img)
    return str(path)


def _diff_images():
    rng = np.random.default_rng(5)
    ref = rng.uniform(0.5, 2.0, (4, 6, 3))
    test = ref + rng.normal(0.0, 0.1, ref.shape)
    return test.astype(np.float32).astype(np.float64), ref.astype(np.float32).astype(np.float64)


def _parse(stdout):
    vals = {}
    for line in stdout.splitlines():
        k, v = line.split(":")
        vals[k.strip()] = float(v)
    return vals


def test_diff_numbers(tmp_path, capsys):
    test, ref = _diff_images()
    rc = main(["diff", _exr(tmp_path / "t.exr", test), _exr(tmp_path / "r.exr", ref)])
    assert rc == 0
    vals = _parse(capsys.readouterr().out)
    d = test - ref
    assert vals["mean_abs"] == pytest.approx(np.mean(np.abs(d)), rel=1e-5)
    assert vals["rms"] == pytest.approx(np.sqrt(np.mean(d * d)), rel=1e-5)
    assert vals["mean_rel"] == pytest.approx(np.mean(np.abs(d) / np.abs(ref)), rel=1e-5)
    assert vals["max_abs"] == pytest.approx(np.max(np.abs(d)), rel=1e-5)
    # sanity: for normal noise of sigma 0.1, mean |d| ≈ 0.1 sqrt(2/pi), rms ≈ 0.1
    assert 0.05 < vals["mean_abs"] < 0.11 and 0.07 < vals["rms"] < 0.13


def test_diff_identical_images_is_zero(tmp_path, capsys):
    _, ref = _diff_images()
    p = _exr(tmp_path / "r.exr", ref)
    assert main(["diff", p, p]) == 0
    vals = _parse(capsys.readouterr().out)
    assert vals["mean_abs"] == 0.0 and vals["rms"] == 0.0 and vals["mean_rel"] == 0.0


def test_diff_relative_error_floor_on_black_pixels(tmp_path, capsys):
    """Black reference pixels: |ref| is floored at 1e-3 of the mean |ref| (metrics.errors docstring)."""
    ref = np.ones((2, 2, 3))
    ref[0, 0] = 0.0
    test = ref.copy()
    test[0, 0] = 0.01
    assert main(["diff", _exr(tmp_path / "t.exr", test), _exr(tmp_path / "r.exr", ref)]) == 0
    vals = _parse(capsys.readouterr().out)
    floor = 1e-3 * np.mean(ref)  # 0.75e-3
    rel = np.zeros(ref.shape)
    rel[0, 0] = np.float32(0.01) / floor
    assert vals["mean_rel"] == pytest.approx(rel.mean(), rel=1e-5)
    assert np.isfinite(vals["mean_rel"])


def test_diff_error_map_colours(tmp_path, capsys):
    """Pixel errors 0, max/2 and max appear blue, green and red in the map."""
    from PIL import Image

    ref = np.full((3, 4, 3), 1.0)
    test = ref.copy()
    test[0, 1] += 0.5            # half of the largest error → green
    test[1, 2] -= 1.0            # the largest error (mean over channels 1.0) → red
    test[2, 3] += [0.25, 0.25, 0.25]  # a quarter → cyan
    m, mx = tmp_path / "map.png", tmp_path / "map.exr"
    assert main(["diff", _exr(tmp_path / "t.exr", test), _exr(tmp_path / "r.exr", ref),
                 "--map", str(m), "--map-exr", str(mx)]) == 0
    with Image.open(m) as im:
        rgb = np.asarray(im.convert("RGB"))
    assert rgb.shape[1] == 4 and rgb.shape[0] > 3  # the image, with a legend strip below
    np.testing.assert_array_equal(rgb[0, 0], (0, 0, 255))
    np.testing.assert_array_equal(rgb[0, 1], (0, 255, 0))
    np.testing.assert_array_equal(rgb[1, 2], (255, 0, 0))
    np.testing.assert_array_equal(rgb[2, 3], (0, 255, 255))
    err, header = film.read_exr(mx)
    expected = np.abs(test - ref).mean(axis=2)
    for c in range(3):
        np.testing.assert_allclose(err[..., c], expected, rtol=1e-7)
    assert float(header["scale_max"]) == pytest.approx(1.0)


def test_diff_map_with_fixed_scale(tmp_path, capsys):
    ref = np.zeros((1, 2, 3))
    test = np.array([[[0.1] * 3, [0.4] * 3]])
    m = tmp_path / "map.png"
    assert main(["diff", _exr(tmp_path / "t.exr", test), _exr(tmp_path / "r.exr", ref), "--map", str(m),
                 "--max", "0.2"]) == 0
    from PIL import Image

    with Image.open(m) as im:
        rgb = np.asarray(im.convert("RGB"))
    np.testing.assert_array_equal(rgb[0, 0], (0, 255, 0))  # 0.1 of 0.2 → midpoint → green
    np.testing.assert_array_equal(rgb[0, 1], (255, 0, 0))  # above the scale → red
