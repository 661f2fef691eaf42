"""The tiles compile nothing the warm-up did not (a compile during the tiles is late: after the compile notice,
inside the render's timing): `renderer._tile_keys`, which every tile calls first, called by `warm_up` in the types
the tiles call it with."""
import numba

from raytrace import api
from raytrace.rendering import renderer


def test_the_warm_up_calls_the_tiles_keys_kernel_in_the_tiles_types(monkeypatch):
    calls, kernel, warm_up = [], renderer._tile_keys, renderer.warm_up

    def spy(*args):
        calls.append((phase[0], tuple(numba.typeof(a) for a in args)))
        return kernel(*args)

    def warming(*args, **kwargs):
        phase[0] = "warm-up"
        try:
            return warm_up(*args, **kwargs)
        finally:
            phase[0] = "tiles"
    phase = ["before"]
    monkeypatch.setattr(renderer, "_tile_keys", spy)
    monkeypatch.setattr(renderer, "warm_up", warming)
    monkeypatch.setattr(renderer, "WARMED", set())
    api.render(None, "analytic", width=12, height=8, spp=2, threads=1)
    warm = {types for when, types in calls if when == "warm-up"}
    tiles = {types for when, types in calls if when == "tiles"}
    assert warm and tiles and tiles <= warm
