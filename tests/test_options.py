"""Render options (raytrace/options.py, checked once by api.render_options), the renderer's executors
and its per-block observer."""
from dataclasses import replace

import numpy as np
import pytest

import raytrace
from raytrace.options import RenderOptions
from raytrace.rendering import renderer
from raytrace.rendering.renderer import prepare, render

from .conftest import box_room


def room(**camera):
    return box_room(camera={"position": [0.3, 0.2, 3.0], "look_at": [0.0, 0.0, -1.0], "fov": 70.0, "width": 12,
                            "height": 9, "spp": 3, **camera})


class Recorder:
    """An observer that counts every pixel it is shown and keeps the last value shown."""

    def __init__(self, width, height):
        self.seen = np.zeros((height, width), dtype=int)
        self.image = np.full((height, width, 3), np.nan)

    def __call__(self, y0, y1, x0, x1, block):
        assert block.shape == (y1 - y0, x1 - x0, 3)
        self.seen[y0:y1, x0:x1] += 1
        self.image[y0:y1, x0:x1] = block


@pytest.fixture
def small_tiles(monkeypatch):
    monkeypatch.setattr(renderer, "SUM_RAYS", 16)  # 12 x 3 rays a row: a pixel's samples in three ranges,
    monkeypatch.setattr(renderer, "RAYS_PER_TILE", 4)  # bands of 4 x 4 // 12 = 1 row,
    monkeypatch.setattr(renderer, "PHASES", 4)  # each in 4 tiles of 3 pixels
    monkeypatch.setattr(renderer, "MIN_TILE_RAYS", 1)


@pytest.mark.parametrize("crop", [None, (2, 1, 9, 7)])
def test_the_observer_sees_every_pixel_once_and_the_blocks_are_the_image(small_tiles, crop):
    prep = prepare(raytrace.load(room()))
    rec = Recorder(12, 9)
    res = render(prep, "analytic", {}, RenderOptions(threads=2, crop=crop, observer=rec))
    x0, y0, x1, y1 = crop or (0, 0, 12, 9)
    assert np.all(rec.seen[y0:y1, x0:x1] == 1) and rec.seen.sum() == (x1 - x0) * (y1 - y0)
    assert rec.image[y0:y1, x0:x1].tobytes() == res.image.tobytes()


def test_progressive_passes_show_the_running_mean_and_the_last_pass_is_the_image(small_tiles):
    """Each pass shows every pixel once, as the mean of the passes so far; the last pass's blocks
    are the final image bit for bit, and observing changes nothing."""
    rec = Recorder(12, 9)
    counted = []
    img = raytrace.render(room(), method="montecarlo", samples=2, seed=3, threads=2, passes=3, observer=rec,
                          on_pass=lambda n, err: counted.append(rec.seen.copy()))
    assert [c.min() for c in counted] == [c.max() for c in counted] == [1, 2, 3]
    assert rec.image.tobytes() == img.array.tobytes()
    plain = raytrace.render(room(), method="montecarlo", samples=2, seed=3, threads=1, passes=3)
    assert plain.array.tobytes() == img.array.tobytes()


class Reversed:
    """An executor that runs the tiles one after another, last tile first."""

    def prepare(self, prep, task):
        return renderer.prepare_task(prep, task)

    def map(self, prep, task, work):
        for i in reversed(range(len(work))):
            yield i, renderer.render_tile(prep, task, work[i])


@pytest.mark.parametrize("method", ["analytic", "montecarlo"])
def test_any_executor_gives_the_same_bytes(small_tiles, method):
    prep = prepare(raytrace.load(room()))
    opts = RenderOptions(seed=5, volumetric_shadows=True)
    pool = render(prep, method, {}, replace(opts, threads=2))
    other = render(prep, method, {}, opts, Reversed())
    assert pool.image.tobytes() == other.image.tobytes() and pool.stats == other.stats
    if pool.variance is not None:
        assert pool.variance.tobytes() == other.variance.tobytes()


@pytest.mark.parametrize("given, words", [
    ({"spp": 0}, ["spp=0", "--spp", "positive integer"]),
    ({"width": 2.5}, ["width=2.5", "--width"]),
    ({"threads": True}, ["threads=True", "--threads"]),
    ({"passes": -1}, ["passes=-1", "--passes"]),
    ({"seed": -2}, ["seed=-2", "--seed", ">= 0"]),
    ({"time_budget": 0.0}, ["time_budget=0.0", "--time-budget", "positive"]),
    ({"target_error": -1e-3}, ["target_error=-0.001", "--target-error"]),
    ({"checkpoint_interval": -1.0}, ["checkpoint_interval=-1.0", "--checkpoint-interval", ">= 0 seconds"]),
    ({"max_memory": 0.0}, ["max_memory=0.0", "--max-memory", "GiB"]),
    ({"crop": (0, 0, 13, 9)}, ["crop=(0, 0, 13, 9)", "--crop", "12x9"]),
])
def test_bad_options_name_the_keyword_and_the_flag(given, words):
    with pytest.raises(raytrace.UserError) as e:
        raytrace.render(room(), method="montecarlo", **given)
    msg = str(e.value)
    assert "\n" not in msg and all(w in msg for w in words), msg


def test_options_come_from_the_scene_render_table_unless_given():
    scene = raytrace.load(room() | {"render": {"seed": 7, "volumetric_shadows": True, "shadow_spacing": 0.02}})
    opts = raytrace.api.render_options(scene, spp=2)
    assert (opts.seed, opts.volumetric_shadows, opts.shadows) == (7, True, True)
    assert scene.camera.spp == 2
    opts = raytrace.api.render_options(scene, seed=1, volumetric_shadows=False)
    assert (opts.seed, opts.shadows) == (1, False)
    with pytest.raises(raytrace.UserError, match="deterministic"):
        raytrace.render(room(), method="analytic", passes=2)
