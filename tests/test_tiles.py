"""The interleaved tiles (renderer.tiles): every pixel in exactly one tile per sample range, no
tile more than about 1/PHASES of a band, and images bit for bit the same whatever the thread count
and tile size, and within 1e-13 relative of 9596215's (tests/make_tile_refs.py renders the stored
ones with that commit's code; the issue's law across versions: analytic's first pass compiled without
the spot and anisotropic code where a scene has none moves the last bits of some values), their
variances, bounds and statistics the same bytes."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

import raytrace
from raytrace.rendering import renderer

from .make_tile_refs import CASES, DATA, render_case


def camera(width, height, spp):  # what tiles() reads of a camera
    return SimpleNamespace(width=width, height=height, spp=spp)


@pytest.mark.parametrize("size", [(1, 1, 1), (7, 3, 5), (160, 120, 1), (640, 480, 1), (1024, 512, 4), (128, 2, 144),
                                  (4096, 16, 8)])
def test_every_pixel_sample_once_and_tiles_small(size):
    w, h, spp = size
    cam = camera(w, h, spp)
    for box in [(0, 0, w, h), (w // 3, h // 3, w, h)]:
        work = renderer.tiles(cam, box)
        x0, y0, x1, y1 = box
        seen = np.zeros((y1 - y0, x1 - x0, spp), dtype=int)
        for t in work:
            q = np.arange(t.pixels.start, t.pixels.stop, t.pixels.step)
            seen[t.rows.start - y0 + q // (x1 - x0), q % (x1 - x0), t.samples] += 1
            band = (t.rows.stop - t.rows.start) * (x1 - x0)
            n = t.samples.stop - t.samples.start
            assert len(q) * n <= 2 * renderer.RAYS_PER_TILE
            # a PHASES-th of the band, or in a small band tiles of at least MIN_TILE_RAYS rays, or one
            assert len(q) <= -(-band // renderer.PHASES) or len(q) * n >= renderer.MIN_TILE_RAYS or len(q) == band
            assert len(q) >= band // renderer.PHASES  # dealt out evenly
        assert np.all(seen == 1)


def test_sample_ranges_are_9596215s():
    """A row of more than SUM_RAYS rays sums its pixels' samples in ranges of SUM_RAYS // width."""
    assert renderer.sample_ranges(camera(128, 2, 144)) == [slice(0, 128), slice(128, 144)]
    assert renderer.sample_ranges(camera(1024, 2, 16)) == [slice(0, 16)]
    assert renderer.sample_ranges(camera(1 << 15, 2, 1)) == [slice(0, 1)]


@pytest.fixture(scope="module")
def stored():
    with np.load(DATA) as z:
        return {k: z[k] for k in z.files}


def same_as_9596215(image, stored_image):
    """Within 1e-13 relative of 9596215's image, value by value (zeros exactly)."""
    np.testing.assert_allclose(image, stored_image, rtol=1e-13, atol=0.0)


@pytest.mark.parametrize("name", list(CASES))
def test_the_same_bytes_whatever_the_threads_and_9596215s_image(name, stored):
    first = render_case(raytrace, name, threads=1)[0]
    same_as_9596215(first, stored[f"{name}/image"])
    for threads in (1, 2, 3):
        image, variance, bound, stats = render_case(raytrace, name, threads=threads)
        assert image.tobytes() == first.tobytes(), threads
        assert variance.tobytes() == stored[f"{name}/variance"].tobytes(), threads
        assert bound.tobytes() == stored[f"{name}/bound"].tobytes(), threads
        assert json.loads(json.dumps(stats, sort_keys=True)) == json.loads(str(stored[f"{name}/stats"])), threads


def test_small_tiles_change_nothing(monkeypatch, stored):
    """Tiles of a few rays each, many bands: the same bytes."""
    first = render_case(raytrace, "analytic_shadows", threads=1)[0]
    monkeypatch.setattr(renderer, "RAYS_PER_TILE", 3)
    monkeypatch.setattr(renderer, "PHASES", 5)
    monkeypatch.setattr(renderer, "MIN_TILE_RAYS", 1)
    image, _, bound, _ = render_case(raytrace, "analytic_shadows", threads=2)
    assert image.tobytes() == first.tobytes()
    assert bound.tobytes() == stored["analytic_shadows/bound"].tobytes()
