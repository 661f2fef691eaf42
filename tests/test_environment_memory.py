"""What a render with an environment light keeps of its pixel samples (rendering/renderer.py `tiles`, `seeded`,
`release`, `Prepared.base`): each pixel sample has its own directions and their shadow frusta; the tiles are one
sample each, the image's samples in turn, and a sample's view is dropped when the last tile of it is done, so
that at most the samples in flight hold frusta (on a9032ee all spp of them stayed until a render with another seed).
The other lights' frusta are the scene's, shared by every sample.
"""
from __future__ import annotations

import weakref

import numpy as np
import pytest

from raytrace import api
from raytrace.lights import environment
from raytrace.rendering import renderer

from .test_environment import ENV, FOG, GROUND, PLATE, scene
from .test_environment_stats import LAMP

CAMERA = {"position": [0.0, 0.6, 3.0], "look_at": [0.0, 0.4, 0.0], "fov": 40.0, "width": 4, "height": 3, "spp": 6}


def fog():
    return scene([ENV, LAMP], medium=FOG, camera=CAMERA, shapes=[GROUND, PLATE])


@pytest.mark.parametrize("threads", [1, 2])
def test_only_the_samples_in_flight_hold_frusta(monkeypatch, threads):
    """Counted at every build of an environment's frusta during a render (spp 6, volumetric shadows): the sets
    alive (weak references, no garbage collection asked for) are at most the threads' samples and the one being
    started, plus the scene's own (warm_up's); none of the samples' is left after the render."""
    built, peak = [], [0]
    build = renderer.build_frusta

    def counted(accel, lights, *args, **kw):
        out = build(accel, lights, *args, **kw)
        at = np.flatnonzero(environment.owned(lights))
        built.append(weakref.ref(out[at[0]]))
        peak[0] = max(peak[0], sum(r() is not None for r in built))
        return out

    monkeypatch.setattr(renderer, "build_frusta", counted)
    api.render(fog(), "quadrature", rtol=1e-6, threads=threads, volumetric_shadows=True, seed=3)
    assert len(built) > CAMERA["spp"]  # every sample built its own
    assert peak[0] <= threads + 2, peak[0]
    assert sum(r() is not None for r in built) <= 1  # the scene's own


def test_the_other_lights_frusta_are_shared():
    """A sample's view builds its environment rows' frusta and takes the lamp's from the scene (the same object)."""
    prep = renderer.prepare(fog())
    view = renderer.seeded(prep, 3, 2, True)
    own = environment.owned(view.lights)
    assert own.any() and not own.all()
    assert all((mine is not base) == o for mine, base, o in zip(view.frusta(), prep.frusta(), own))
    assert not np.array_equal(view.lights.axis[own], prep.lights.axis[own])


def test_the_tiles_share_a_sample_until_the_last():
    """`seeded` with the tiles' uses gives one view to them and drops it after the last `release`."""
    prep = renderer.prepare(fog())
    views = [renderer.seeded(prep, 3, 1, True, ("band", 2)) for _ in range(2)]
    assert views[0] is views[1]
    renderer.release(prep, 3, 1, "band")
    assert renderer.seeded(prep, 3, 1, True, ("band", 2)) is views[0]
    renderer.release(prep, 3, 1, "band")
    renderer.release(prep, 3, 1, "band")
    assert renderer.seeded(prep, 3, 1, True, ("band", 2)) is not views[0]


def test_a_workers_views_last_while_in_flight():
    """Without the uses (a cluster's worker, given some of the tiles) a sample's view stays while a tile of it is in
    flight or until a tile of another sample starts; `forget` (the render over) drops the idle ones at once and the
    others after their tiles in flight."""
    prep = renderer.prepare(fog())
    one = renderer.seeded(prep, 3, 1, band=("tiles", None))
    renderer.release(prep, 3, 1, "tiles")
    assert renderer.seeded(prep, 3, 1, band=("tiles", None)) is one  # the next tile of sample 1: kept
    two = renderer.seeded(prep, 3, 2, band=("tiles", None))
    assert renderer.seeded(prep, 3, 1, band=("tiles", None)) is one  # still in flight
    for _ in range(2):
        renderer.release(prep, 3, 1, "tiles")
    renderer.release(prep, 3, 2, "tiles")
    three = renderer.seeded(prep, 3, 3, band=("tiles", None))
    assert renderer.seeded(prep, 3, 1, band=("tiles", None)) is not one  # idle when sample 3 started: dropped
    assert renderer.seeded(prep, 3, 2, band=("tiles", None)) is not two
    renderer.release(prep, 3, 2, "tiles")
    renderer.forget(prep, 3)
    assert set(prep._memo["seeded"][1]) == {("tiles", 1), ("tiles", 3)}  # in flight
    renderer.release(prep, 3, 1, "tiles")
    renderer.release(prep, 3, 3, "tiles")
    assert prep._memo["seeded"][1] == {} and three._memo == {}


class Camera:  # what tiles() reads of a camera
    def __init__(self, width, height, spp):
        self.width, self.height, self.spp = width, height, spp


@pytest.mark.parametrize("width, height, spp", [(4, 3, 6), (300, 200, 64), (2100, 3, 8)])
def test_tiles_by_sample(width, height, spp):
    """Tiles of one sample each, the image's tiles sample after sample: every pixel once per sample, and
    `tile_uses` counts the tiles of each sample."""
    cam = Camera(width, height, spp)
    box = (0, 0, width, height)
    work = renderer.tiles(cam, box, by_sample=True)
    seen = np.zeros((height * width, spp), int)
    for t in work:
        assert t.samples.stop - t.samples.start == 1
        q = np.arange(t.pixels.stop)[t.pixels] + t.rows.start * width
        seen[q, t.samples.start] += 1
    assert np.all(seen == 1)
    samples = [t.samples.start for t in work]
    assert samples == sorted(samples)  # the whole image's tiles sample after sample (each sample's frusta once)
    prep = type("P", (), {"scene": type("S", (), {"camera": cam}), "memo": lambda self, key, f: f()})()
    uses = renderer.tile_uses(prep, box)
    assert sum(uses.values()) == len(work) and all(uses[s] == samples.count(s) for s in range(spp))


def test_each_sample_builds_its_frusta_once_whatever_the_bands(monkeypatch):
    """With bands of one row (three here), each pixel sample's environment frusta are built once, not once a band."""
    monkeypatch.setattr(renderer, "RAYS_PER_TILE", 4)
    monkeypatch.setattr(renderer, "PHASES", 2)
    assert len({t.rows.start for t in renderer.tiles(Camera(4, 3, 6), (0, 0, 4, 3), by_sample=True)}) == 3
    views, build = [], renderer.build_frusta

    def counted(accel, lights, *args, rows=None, **kw):
        views.append(rows is not None)
        return build(accel, lights, *args, rows=rows, **kw)

    monkeypatch.setattr(renderer, "build_frusta", counted)
    api.render(fog(), "quadrature", rtol=1e-6, threads=2, volumetric_shadows=True, seed=3)
    assert sum(views) == CAMERA["spp"], sum(views)
