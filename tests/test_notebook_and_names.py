"""Notebook display of an `Image` (_repr_png_, _repr_html_) and "did you mean" for method and scene names."""
from __future__ import annotations

import base64
import io

import numpy as np
import pytest
from PIL import Image as Picture

import raytrace
from raytrace.api import PREVIEW_WIDTH
from raytrace.cli import main
from raytrace.output import view

from .conftest import box_room


def _decode(data: bytes) -> np.ndarray:
    with Picture.open(io.BytesIO(data)) as im:
        return np.asarray(im.convert("RGB"))


def test_a_small_image_previews_at_its_size_through_the_view():
    img = raytrace.render(box_room(), width=8, height=6, threads=1)
    np.testing.assert_array_equal(_decode(img._repr_png_()), view.to_display(img.array))


def test_a_wide_image_is_shrunk_to_the_preview_width():
    img = raytrace.render(box_room(), width=8, height=6, threads=1)
    img.array = np.repeat(np.repeat(img.array, 120, axis=0), 120, axis=1)  # 960 x 720 of 120 x 120 blocks
    small = _decode(img._repr_png_())
    assert small.shape == (360, PREVIEW_WIDTH, 3)
    np.testing.assert_array_equal(small[::60, ::60], view.to_display(img.array)[::120, ::120])  # block centres


def test_the_html_has_the_preview_and_a_caption():
    img = raytrace.render(box_room(name="room <1>"), method="analytic", width=8, height=6, threads=1)
    text = img._repr_html_()
    data = text.split('base64,')[1].split('"')[0]
    assert base64.b64decode(data) == img._repr_png_()
    assert f"room &lt;1&gt;: 8x6, method analytic, {img.spp} spp, {img.seconds:.2f} s" in text


@pytest.mark.parametrize("argv, message", [
    (["box_rom"], 'box_rom: no such scene file or bundled scene; did you mean "box_room"?'),
    (["box_room", "--method", "analytc"], 'unknown method; did you mean "analytic"? choose one of: analytic,'),
])
def test_did_you_mean(tmp_path, capsys, argv, message):
    assert main(argv + ["--out", str(tmp_path / "a.exr")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and not (tmp_path / "a.exr").exists()


def test_a_name_close_to_nothing_lists_the_choices():
    with pytest.raises(raytrace.UserError, match=r"^qqqq: no such scene file or bundled scene; give .*: box_room, "):
        raytrace.load("qqqq")
    with pytest.raises(raytrace.UserError, match=r"method='qqqq' .*unknown method; choose one of: "):
        raytrace.render(box_room(), method="qqqq")
