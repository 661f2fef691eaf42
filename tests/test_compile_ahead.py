"""The first render's compile split over two processes (rendering/compile_ahead.py): the main
process's disk cache held (`jit.hold`: no loads, saves kept back) until the worker has finished, the
air-light gated on the worker, engaged for the first warm-up (shadowed) of a process that started on
an empty cache, or for the cubature pilot's (unshadowed) before a shadowed render, kept until the
render's warm-up settles it; and, in fresh processes on empty caches, the same image every time with
the air-light's kernels (or the shadows', beside a pilot; or the media inside shapes') loaded from what the
worker compiled."""
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from raytrace import jit
from raytrace.jit import njit
from raytrace.rendering import compile_ahead

pytestmark = pytest.mark.skipif(not jit.CUTS, reason="this numba's internals differ from 0.68's: plain numba.njit")
ROOT = Path(__file__).resolve().parents[1]


@njit
def _held_kernel(x):
    return 3.0 * x - 1.0


def test_a_held_cache_neither_loads_nor_saves_until_released(monkeypatch):
    loads, saves = [], []
    inner = type(_held_kernel._cache._cache)
    monkeypatch.setattr(inner, "load_overload", lambda self, sig, ctx: loads.append(sig))
    monkeypatch.setattr(inner, "save_overload", lambda self, sig, cres: saves.append(sig))
    jit.hold()
    try:
        assert _held_kernel(2.0) == 5.0  # compiled here: no load tried, its save kept back
        assert loads == [] and saves == []
    finally:
        jit.release()
    (sig,) = _held_kernel.overloads
    assert saves == [sig] and jit._held is None  # written at the release
    assert _held_kernel._cache.load_overload(sig, None) is None and loads == [sig]  # loads go through again


class _Ahead:
    def __init__(self, log):
        self.log = log

    def wait(self):
        self.log.append("wait")


def test_a_failed_warm_up_ends_the_worker_and_releases_the_cache(monkeypatch):
    monkeypatch.setattr(compile_ahead, "_started", [])
    monkeypatch.setattr(jit, "CACHE_EMPTY", True)
    ahead = compile_ahead.start(True, time.sleep, 600.0)  # a worker that would run for ten minutes
    if ahead is None:
        pytest.skip("one core: no worker")
    assert jit._held == []
    start = time.perf_counter()
    ahead.wait(stop=True)
    assert time.perf_counter() - start < 60.0 and jit._held is None
    ahead.wait()  # once only


def test_a_worker_for_a_later_warm_up_is_kept_until_settled(monkeypatch):
    monkeypatch.setattr(compile_ahead, "_started", [])
    monkeypatch.setattr(compile_ahead, "_later", [])
    monkeypatch.setattr(jit, "CACHE_EMPTY", True)
    assert compile_ahead.start(True, time.sleep, 0.5, later=True) is None  # this warm-up waits for nothing
    if not compile_ahead._later:
        pytest.skip("one core: no worker")
    assert jit._held == []  # held from the worker's start ...
    assert compile_ahead.settle() > 0.0  # ... until the later warm-up has waited for it
    assert compile_ahead._later == [] and jit._held is None
    assert compile_ahead.settle() < 0.1  # nothing left to wait for
    assert compile_ahead.start(True, time.sleep, 600.0, later=True) is None  # not the first warm-up: no worker
    assert compile_ahead._later == []


def test_a_failed_pilot_ends_the_later_worker(monkeypatch):
    monkeypatch.setattr(compile_ahead, "_started", [])
    monkeypatch.setattr(compile_ahead, "_later", [])
    monkeypatch.setattr(jit, "CACHE_EMPTY", True)
    compile_ahead.start(True, time.sleep, 600.0, later=True)
    if not compile_ahead._later:
        pytest.skip("one core: no worker")
    assert compile_ahead.settle(stop=True) < 60.0 and jit._held is None


class _Method:
    name = "fake"

    def __init__(self, log):
        self.log = log

    def airlight(self, *args):
        self.log.append(("airlight", args))
        return 7


def test_the_gated_airlight_waits_for_the_worker_first():
    log = []
    gated = compile_ahead.Gated(_Method(log), _Ahead(log))
    assert gated.name == "fake" and log == []  # everything else is the method's, ungated
    assert gated.airlight(1, 2) == 7
    assert log == ["wait", ("airlight", (1, 2))]


def test_engaged_for_a_first_shadowed_warm_up_in_a_process_that_started_on_an_empty_cache(monkeypatch):
    monkeypatch.delenv("RAYTRACE_COMPILE_AHEAD", raising=False)
    monkeypatch.setattr(jit, "CACHE_EMPTY", False)
    assert not compile_ahead.engaged()
    monkeypatch.setattr(jit, "CACHE_EMPTY", True)
    many = (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1) > 1
    assert compile_ahead.engaged() == many
    monkeypatch.setenv("RAYTRACE_COMPILE_AHEAD", "0")
    assert not compile_ahead.engaged()
    monkeypatch.delenv("RAYTRACE_COMPILE_AHEAD")
    monkeypatch.setattr(compile_ahead, "_started", [])
    assert compile_ahead.start(False, print) is None  # an unshadowed first warm-up (a cubature pilot's) ...
    assert compile_ahead.start(True, print) is None  # ... leaves the process's compile to itself
    assert len(compile_ahead._started) == 2 and jit._held is None


RENDER = """
import json, sys
import numpy as np
from raytrace import api
from raytrace.methods import analytic
image = api.render(sys.argv[2] if len(sys.argv) > 2 else None, "analytic", width=12, height=8, spp=1, threads=1)
np.save(sys.argv[1], image.array)
print(json.dumps({"hits": sum(analytic.evaluate_segments.stats.cache_hits.values()),
                  "misses": sum(analytic.evaluate_segments.stats.cache_misses.values())}))
"""


def _first_render(tmp_path, name, ahead, script, *args):
    """The image and the kernel's cache statistics of `script`'s render in a fresh process on an empty cache."""
    env = dict(os.environ, RAYTRACE_CACHE=str(tmp_path / f"cache_{name}"), PYTHONPATH=str(ROOT),
               RAYTRACE_COMPILE_AHEAD="1" if ahead else "0")
    out = tmp_path / f"{name}.npy"
    proc = subprocess.run([sys.executable, "-c", script, str(out), *args], env=env, capture_output=True, text=True,
                          check=True)
    return np.load(out), json.loads(proc.stdout.splitlines()[-1])


PILOT = """
import json, sys
import numpy as np
from raytrace import api
from raytrace.shadows import frusta
image = api.render(sys.argv[2], "analytic", width=16, height=12, spp=1, threads=1,
                   volumetric_shadows=True, precision=1e-1)
np.save(sys.argv[1], image.array)
kernels = (frusta._point_lit, *frusta._kernels(frusta.POINTS))  # the penumbrae's, and the lit intervals' three
print(json.dumps({"hits": sum(sum(k.stats.cache_hits.values()) for k in kernels),
                  "misses": sum(sum(k.stats.cache_misses.values()) for k in kernels)}))
"""



@pytest.mark.slow
@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="compile ahead needs two cores")
@pytest.mark.parametrize("script, args, n", [(RENDER, (), 1), (RENDER, (str(ROOT / "scenes/stage.toml"),), 1),
                                             (PILOT, (str(ROOT / "tests/data/area_peers/occluded.toml"),), 4)],
                         ids=["airlight", "airlight: spot lights", "beside a pilot: shadows"])
def test_first_renders_on_empty_caches_load_the_workers_kernel_and_agree(tmp_path, script, args, n):
    """The default scene and stage (spot lights, an anisotropic medium): the air-light's kernel, which the
    worker compiles on segments of its own (renderer.axis_segments); an area light's scene, whose cubature
    pilot warms up first: the penumbrae's kernel and the lit intervals' (the shadows' group, which the worker
    compiles on segments of its own too): the render's process compiles none of them."""
    a, stats_a = _first_render(tmp_path, "a", True, script, *args)
    b, stats_b = _first_render(tmp_path, "b", True, script, *args)
    serial, stats_serial = _first_render(tmp_path, "serial", False, script, *args)
    assert stats_a == stats_b == {"hits": n, "misses": 0}  # the worker's kernels, loaded
    assert stats_serial == {"hits": 0, "misses": n}  # compiled in the process
    np.testing.assert_array_equal(a, b)  # which process compiles what does not depend on timing
    np.testing.assert_allclose(a, serial, rtol=1e-13, atol=0)  # the same kernel, compiled elsewhere


INTERIOR = """
import json, sys
import numpy as np
from raytrace import api
from raytrace.media import slab
image = api.render(sys.argv[2], "quadrature", width=16, height=12, spp=1, threads=1, volumetric_shadows=True)
np.save(sys.argv[1], image.array)
print(json.dumps({"hits": sum(slab._convex_quad.stats.cache_hits.values()),
                  "misses": sum(slab._convex_quad.stats.cache_misses.values())}))
"""


@pytest.mark.slow
@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="compile ahead needs two cores")
def test_the_worker_compiles_the_media_inside_shapes_and_the_render_loads_them(tmp_path):
    """wax: the inside integrals' kernel (`slab._convex_quad`) compiled by the worker beside the render's
    warm-up (`renderer.interiors_ahead`), whose rays into the block wait for it and load it."""
    wax = str(ROOT / "scenes" / "wax.toml")
    a, stats_a = _first_render(tmp_path, "a", True, INTERIOR, wax)
    b, stats_b = _first_render(tmp_path, "b", True, INTERIOR, wax)
    serial, stats_serial = _first_render(tmp_path, "serial", False, INTERIOR, wax)
    assert stats_a == stats_b == {"hits": 1, "misses": 0}  # the worker's kernel, loaded
    assert stats_serial == {"hits": 0, "misses": 1}  # compiled in the process
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(a, serial, rtol=1e-13, atol=0)


def test_the_workers_segments_have_the_warm_ups_types():
    """`renderer.axis_segments` (the worker's air-light, `compile_airlight`, from the scene's lights alone) give
    every array the numba type of the warm-up's segments (its camera rays cut at the spot lights' cones,
    `cone_segments`), so the kernels the worker compiles on them are those the render's process loads; one
    segment per light, a piece of a line of sight (t0 > 0, as the lit intervals' are)."""
    import numba
    from raytrace import api
    from raytrace.rendering import renderer
    from raytrace.segments import cone_segments, whole_rays

    prep = renderer.prepare(api.load(str(ROOT / "scenes" / "stage.toml")))
    o, d = renderer.warm_up_rays(prep)
    t, _, _ = renderer.first_hits(prep.accel, prep.scene.medium, o, d)
    warm, _ = cone_segments(whole_rays(o, d, t, np.zeros(len(o), np.uint64), len(prep.lights), 3, prep.accel.scale),
                            prep.lights)
    axis = renderer.axis_segments(prep.scene.camera, prep.lights, 3)
    for field in ("origins", "dirs", "length", "light", "ray", "t0", "keys", "stream"):
        assert numba.typeof(getattr(axis, field)) == numba.typeof(getattr(warm, field)), field
    assert (type(axis.seed), type(axis.scale), axis.per_ray) == (type(warm.seed), type(warm.scale), warm.per_ray)
    assert np.array_equal(axis.light, np.arange(len(prep.lights))) and np.all(axis.t0 > 0.0)
    np.testing.assert_allclose(axis.origins, prep.scene.camera.position + axis.t0[:, None] * axis.dirs)


RECURRENCES = """
import json, sys
import numpy as np
from raytrace import api
from raytrace.methods import analytic
image = api.render(sys.argv[2], "analytic", width=12, height=8, spp=1, threads=1)
np.save(sys.argv[1], image.array)
print(json.dumps({k.__name__: [sum(k.stats.cache_hits.values()), sum(k.stats.cache_misses.values())]
                  for k in (analytic.evaluate_segments, analytic._pending_recurrences)}))
"""


@pytest.mark.slow
@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="compile ahead needs two cores")
def test_the_render_compiles_the_recurrences_while_the_worker_compiles_the_rest(tmp_path):
    """shafts (point lights in HG): the worker compiles the segments' kernel without the moment recurrences,
    which the render's process compiles meanwhile (`compile_ahead.compile_here`) and does not load: hits and
    misses of (`evaluate_segments`, `_pending_recurrences`)."""
    shafts = str(ROOT / "scenes" / "shafts.toml")
    a, stats_a = _first_render(tmp_path, "a", True, RECURRENCES, shafts)
    b, stats_b = _first_render(tmp_path, "b", True, RECURRENCES, shafts)
    serial, stats_serial = _first_render(tmp_path, "serial", False, RECURRENCES, shafts)
    assert stats_a == stats_b == {"evaluate_segments": [1, 0], "_pending_recurrences": [0, 1]}
    assert stats_serial == {"evaluate_segments": [0, 1], "_pending_recurrences": [0, 1]}
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(a, serial, rtol=1e-13, atol=0)
