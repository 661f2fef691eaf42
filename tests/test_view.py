"""Previews (raytrace/view.py): ACES 2.0's SDR view through OpenColorIO, exposure in stops."""
import math

import numpy as np
import pytest

import raytrace
from raytrace import view
from raytrace.errors import UserError


def test_auto_exposure_puts_the_log_average_at_middle_grey():
    img = np.full((4, 6, 3), 0.02)
    img[0, 0] = 0.0  # black pixels do not count
    assert view.auto_exposure(img) == pytest.approx(math.log2(0.18 / 0.02), abs=1e-12)
    two = np.concatenate([np.full((1, 2, 3), 0.01), np.full((1, 2, 3), 1.0)])
    assert view.auto_exposure(two) == pytest.approx(math.log2(0.18) - 0.5 * math.log2(0.01), abs=1e-12)
    assert view.auto_exposure(np.zeros((3, 3, 3))) == 0.0


def test_one_stop_is_a_factor_of_two():
    rng = np.random.default_rng(3)
    img = rng.lognormal(-2.0, 1.5, (16, 16, 3))
    np.testing.assert_array_equal(view.to_display(2.0 * img, 0.5), view.to_display(img, 1.5))
    np.testing.assert_array_equal(view.to_display(img), view.to_display(img, view.auto_exposure(img)))


def test_greys_stay_neutral_and_monotone_black_stays_black():
    ramp = np.logspace(-4, 3, 64)[None, :, None] * np.ones((1, 1, 3))
    out = view.to_display(ramp, 0.0).astype(int)[0]
    assert np.all(np.abs(out[:, 0] - out[:, 1]) <= 1) and np.all(np.abs(out[:, 1] - out[:, 2]) <= 1)
    assert np.all(np.diff(out[:, 1]) >= 0) and out[0, 1] < 10 and out[-1, 1] >= 250
    assert view.to_display(np.zeros((2, 2, 3)), 0.0).max() == 0


def test_saturated_colours_are_not_clipped_channel_by_channel():
    """A plain sRGB encode clips a bright saturated cyan to (0, 255, 255) and loses its shading;
    the view keeps a gradient in both bright channels over two stops above middle grey."""
    cyan = np.array([0.02, 0.5, 0.6]) * np.logspace(0, 0.6, 16)[:, None]
    out = view.to_display(cyan[None], 1.0).astype(int)[0]
    assert np.all(np.diff(out[:, 1]) > 0) and np.all(np.diff(out[:, 2]) > 0) and out.max() < 255


def test_non_finite_pixels_and_exposures():
    img = np.array([[[np.nan, 0.1, 0.1], [np.inf, np.inf, np.inf]]])
    out = view.to_display(img, 0.0)
    assert out[0, 1].min() >= 250
    for bad in (math.nan, math.inf, "bright", True):
        with pytest.raises(UserError, match="not a finite number of stops"):
            view.to_display(img, bad)


@pytest.mark.parametrize("scene", [None, "ocean"])
def test_bundled_previews_clip_at_most_two_percent(scene):
    img = raytrace.render(scene, width=96, height=54, threads=1).array
    out = view.to_display(img)
    assert max(float(np.mean(out[..., c] == 255)) for c in range(3)) <= 0.02
