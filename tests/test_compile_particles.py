"""The particle layer's kernels (media/particles.py) are compiled by the render's process, which adds the layer
after the air-light: with a compile worker, the warm-up compiles them before the worker's gate
(`renderer.particles_ahead`), not after the wait, with the argument types `shade_rays` gives them (so that
they are compiled once)."""
from pathlib import Path

import numba
import pytest

from raytrace import api, jit
from raytrace.media import particles
from raytrace.methods import get_method, resolve_params
from raytrace.rendering import compile_ahead, renderer

pytestmark = pytest.mark.skipif(not jit.CUTS, reason="this numba's internals differ from 0.68's: plain numba.njit")
ROOT = Path(__file__).resolve().parents[1]


class _Ahead:
    """A worker that has finished: its gate logs the wait."""

    def __init__(self, log):
        self.log = log

    def wait(self, stop=False):
        self.log.append("gate")


def test_the_particles_kernels_compile_before_the_gate(monkeypatch):
    log, types = [], []
    march = particles._march

    def spy(fill, *args):
        log.append("particles")
        types.append(tuple(numba.typeof(a) for a in args))
        return march(fill, *args)
    monkeypatch.setattr(particles, "_march", spy)
    monkeypatch.setattr(compile_ahead, "start", lambda *args, **kwargs: _Ahead(log))
    monkeypatch.setattr(renderer, "WARMED", set())
    prep = renderer.prepare(api.load(str(ROOT / "scenes" / "particles_shaft.toml"),
                                     ["camera.width=8", "camera.height=6"]))
    method = get_method("analytic")
    renderer.warm_up(prep, method, resolve_params(method, {"precision": 1e-2}, "test"), 1)
    assert log.index("particles") < log.index("gate")  # (two calls a warm-up: counting, then filling)
    assert log.count("particles") == 4 and len(set(types)) == 1  # before the gate and in the shading: one typing
