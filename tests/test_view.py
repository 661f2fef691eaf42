"""Previews (raytrace/output/view.py): Khronos PBR Neutral (the default view) and ACES 2.0's SDR view
through OpenColorIO, exposure in stops."""
import colorsys
import math
import tomllib

import numpy as np
import pytest

import raytrace
from raytrace.default_scene import DEFAULT_TOML
from raytrace.errors import UserError
from raytrace.output import film, view

VIEWS = view.DISPLAY_VIEWS


def test_auto_exposure_puts_the_log_average_at_middle_grey():
    img = np.full((4, 6, 3), 0.02)
    img[0, 0] = 0.0  # black pixels do not count
    assert view.auto_exposure(img) == pytest.approx(math.log2(0.18 / 0.02), abs=1e-12)
    two = np.concatenate([np.full((1, 2, 3), 0.01), np.full((1, 2, 3), 1.0)])
    assert view.auto_exposure(two) == pytest.approx(math.log2(0.18) - 0.5 * math.log2(0.01), abs=1e-12)
    assert view.auto_exposure(np.zeros((3, 3, 3))) == 0.0


def test_pbr_neutral_matches_the_specification_by_hand():
    """Values worked by hand from the Khronos README's equations: the toe f = x - x^2 / (4 F90) below
    2 F90 = 0.08 and F90 = 0.04 above; identity minus f up to K_S = 0.76; above it a grey 2.0 has
    p = 1.96, p_n = 1 - 0.24^2 / (1.96 - 0.52) = 0.96 and g = 1 / (0.15 (1.96 - 0.96) + 1) = 1 / 1.15."""
    grey = np.array([0.0, 0.04, 0.08, 0.5, 0.8, 2.0])[:, None] * np.ones(3)
    want = np.array([0.0, 0.04 ** 2 / 0.16, 0.08 ** 2 / 0.16, 0.46, 0.76, 0.96])
    np.testing.assert_allclose(view.pbr_neutral(grey), want[:, None] * np.ones(3), rtol=1e-14, atol=1e-16)
    c = np.array([1.96, 0.96, 0.46])  # [2, 1, 0.5] less f = 0.04: scaled by p_n / p g, mixed with p_n (1 - g)
    np.testing.assert_allclose(view.pbr_neutral(np.array([2.0, 1.0, 0.5])), (c * 0.96 / 1.96 + 0.96 * 0.15) / 1.15,
                               rtol=1e-14)
    lamp = np.array([0.3, 0.6, 1.2])  # below K_S nothing but the offset: hue and chroma as given
    np.testing.assert_allclose(view.pbr_neutral(lamp / 2), lamp / 2 - 0.04, rtol=1e-14)


def test_the_neutral_tone_curve_is_monotone_continuous_and_below_one():
    x = np.concatenate([np.linspace(0.0, 2.0, 20001), np.logspace(0.31, 12, 2000)])
    for colour in ([1.0, 1.0, 1.0], [1.0, 0.6, 0.3], [0.05, 0.3, 1.0], [1.0, 0.0, 0.0]):
        out = view.pbr_neutral(x[:, None] * np.array(colour))
        peak = out.max(axis=-1)
        assert np.all(np.diff(peak) >= 0.0) and np.all(np.diff(out, axis=0) >= -1e-15)  # every channel rises
        assert np.all(peak < 1.0) and np.max(np.diff(peak[:20001])) <= 1e-4 * (1 + 1e-9)  # slope <= 1: no jump
    at = view.K_S + view.F90  # the grey whose peak after the offset is K_S, where compression starts
    np.testing.assert_allclose(view.pbr_neutral(np.full(3, at * (1 + 1e-12))), view.K_S, rtol=1e-11)
    lum = view.pbr_neutral(np.logspace(-4, 4, 4001)[:, None] * np.ones(3))[:, 0]
    assert np.all(np.diff(lum) > 0.0)


@pytest.mark.parametrize("name", VIEWS)
def test_one_stop_is_a_factor_of_two(name):
    rng = np.random.default_rng(3)
    img = rng.lognormal(-2.0, 1.5, (16, 16, 3))
    np.testing.assert_array_equal(view.to_display(2.0 * img, 0.5, name), view.to_display(img, 1.5, name))
    np.testing.assert_array_equal(view.to_display(img, None, name),
                                  view.to_display(img, view.auto_exposure(img), name))


@pytest.mark.parametrize("name", VIEWS)
def test_greys_stay_neutral_and_monotone_black_stays_black(name):
    ramp = np.logspace(-4, 3, 64)[None, :, None] * np.ones((1, 1, 3))
    out = view.to_display(ramp, 0.0, name).astype(int)[0]
    assert np.all(np.abs(out[:, 0] - out[:, 1]) <= 1) and np.all(np.abs(out[:, 1] - out[:, 2]) <= 1)
    assert np.all(np.diff(out[:, 1]) >= 0) and out[0, 1] < 10 and out[-1, 1] >= 250
    assert view.to_display(np.zeros((2, 2, 3)), 0.0, name).max() == 0


def test_saturated_colours_are_not_clipped_channel_by_channel():
    """A plain sRGB encode clips a bright saturated cyan to (0, 255, 255) and loses its shading;
    the views keep a gradient in both bright channels over two stops above middle grey: ACES rises at
    every step, PBR Neutral, which compresses the peak harder near white and desaturates it towards white,
    never falls and rises by at least 8 codes in each bright channel (the plain encode: 0)."""
    cyan = np.array([0.02, 0.5, 0.6]) * np.logspace(0, 0.6, 16)[:, None]
    out = view.to_display(cyan[None], 1.0, "aces").astype(int)[0]
    assert np.all(np.diff(out[:, 1]) > 0) and np.all(np.diff(out[:, 2]) > 0) and out.max() < 255
    out = view.to_display(cyan[None], 1.0, "neutral").astype(int)[0]
    assert np.all(np.diff(out, axis=0) >= 0) and np.all(out[-1, 1:] - out[0, 1:] >= 8) and out.max() < 255


@pytest.mark.parametrize("name", VIEWS)
def test_non_finite_negative_and_zero_pixels_and_exposures(name):
    img = np.array([[[np.nan, 0.1, 0.1], [np.inf, np.inf, np.inf], [np.inf, 0.0, 0.0], [-1.0, -np.inf, 0.0],
                     [0.0, 0.0, 0.0], [1e300, 1e300, 1e-300]]])
    with np.errstate(over="raise", divide="raise", invalid="raise"):  # no inf or nan made on the way
        out = view.to_display(img, 0.0, name)
    assert out[0, 1].min() >= 250 and out[0, 3].max() == 0 and out[0, 4].max() == 0  # nan counts as 0
    assert out[0, 2, 0] >= 250 and out[0, 5, 0] >= 250  # an infinite or huge channel is at the top
    for bad in (math.nan, math.inf, "bright", True):
        with pytest.raises(UserError, match="not a finite number of stops"):
            view.to_display(img, bad, name)


@pytest.fixture(scope="module")
def bundled():
    """The default scene and the ocean at 96 x 54, each scene's own method."""
    return {scene: raytrace.render(scene, width=96, height=54, threads=1).array for scene in (None, "ocean")}


@pytest.mark.parametrize("name", VIEWS)
@pytest.mark.parametrize("scene", [None, "ocean"])
def test_bundled_previews_clip_at_most_two_percent(bundled, scene, name):
    out = view.to_display(bundled[scene], None, name)
    assert max(float(np.mean(out[..., c] == 255)) for c in range(3)) <= 0.02


def _lamp_pixels(image):
    """For each of the default scene's lamps, the brightest pixel within a tenth of the width of where
    the lamp projects (from the scene file's camera) at which the standard view clips no channel."""
    scene = tomllib.loads(DEFAULT_TOML)
    cam = scene["camera"]
    eye = np.array(cam["position"])
    ahead = np.array(cam["look_at"]) - eye
    ahead /= np.linalg.norm(ahead)
    right = np.cross(ahead, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, ahead)
    h, w, _ = image.shape
    tan = math.tan(math.radians(cam["fov"]) / 2.0)
    standard = film.tonemap(image, None, "standard")
    lum = image @ view.LUMINANCE
    rows, cols = np.mgrid[0:h, 0:w] + 0.5
    for light in scene["light"]:
        d = np.array(light["position"]) - eye
        col = (d @ right / (d @ ahead) / tan * h / w + 1.0) / 2.0 * w
        row = (1.0 - d @ up / (d @ ahead) / tan) / 2.0 * h
        near = ((rows - row) ** 2 + (cols - col) ** 2 < (0.1 * w) ** 2) & (standard.max(axis=-1) < 255)
        yield light["intensity"], np.unravel_index(np.argmax(np.where(near, lum, -1.0)), lum.shape), standard


def _hsv(rgb8):
    return colorsys.rgb_to_hsv(*(np.asarray(rgb8) / 255.0))


def test_lamps_keep_their_hue_and_colour_where_aces_greys_them(bundled):
    """Near each coloured lamp of the default scene the neutral view's hue is the standard view's within
    3 degrees and its saturation (HSV) at least 0.7 of it; ACES 2.0 keeps the hue but not half the
    saturation (the washed-out lamps of issue 39)."""
    image = bundled[None]
    neutral, aces = view.to_display(image), view.to_display(image, None, "aces")
    for intensity, pixel, standard in _lamp_pixels(image):
        (h_std, s_std, _), (h, s, _), (_, s_aces, _) = (_hsv(x[pixel]) for x in (standard, neutral, aces))
        assert s_std > 0.1, (intensity, standard[pixel])  # a coloured pixel, not a white one
        assert abs((h - h_std + 0.5) % 1.0 - 0.5) * 360.0 <= 3.0, (intensity, neutral[pixel], standard[pixel])
        assert s >= 0.7 * s_std, (intensity, neutral[pixel], standard[pixel])
        assert s_aces < 0.5 * s_std, (intensity, aces[pixel], standard[pixel])
