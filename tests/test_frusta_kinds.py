"""The volumetric shadows' kernels of a scene without a directional light (shadows/frusta.py `_kernels`:
the POINTS variant, whose sun's code numba prunes) give the same texel lists and lit
pieces, bit for bit, as the kernels with both kinds' code (`sun` a bool at run time, as in a scene
with a sun), on a random triangle soup under a point light, for segments from random points in
random directions (some unbounded)."""
import numpy as np

from raytrace.methods import Segments
from raytrace.shadows import frusta


def soup(rng, n=300):
    centres = rng.uniform(-3, 3, (n, 1, 3))
    return centres + rng.normal(size=(n, 3, 3)) * 0.4


def segments(rng, n, light):
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    length = rng.uniform(0.0, 8.0, n)
    length[::7] = np.inf
    zeros = np.zeros(n, np.int64)
    return Segments(rng.uniform(-5, 5, (n, 3)), dirs, length, np.full(n, light, np.int64), np.arange(n), np.zeros(n),
                    zeros, zeros)


def test_point_lights_without_the_suns_code_give_the_same_pieces():
    rng = np.random.default_rng(11)
    tris = soup(rng)
    frame = np.array([[0.3, 0.2, 0.1], [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    pruned = frusta._light_bins(tris, frame, False, 16, 1e-6, frusta.REL * 10, suns=False)
    both = frusta._light_bins(tris, frame, False, 16, 1e-6, frusta.REL * 10, suns=True)
    for name in ("planes", "signs", "start", "tri", "lb", "cover", "cover_depth", "grid", "frame"):
        assert np.array_equal(getattr(pruned, name), getattr(both, name)), name
    sun = frusta.sun_bins(tris, np.array([0.3, -1.0, 0.2]), 1e-6, 10.0, 16)
    segs = segments(rng, 2000, 0)
    stats_pruned, stats_both = np.zeros(len(frusta.STATS_NAMES)), np.zeros(len(frusta.STATS_NAMES))
    got_pruned = frusta.lit_pieces(segs, [pruned], 10.0, stats_pruned)  # no sun among the bins
    got_both = frusta.lit_pieces(segs, [both, sun], 10.0, stats_both)  # a sun among them
    assert 0 < stats_pruned[frusta.ST_FRUSTA] and 0 < stats_pruned[frusta.ST_DARK]  # shadows were found
    assert len(got_pruned[0]) > len(segs.length) // 2
    for x, y in zip(got_pruned, got_both):
        assert np.array_equal(x, y)
    assert np.array_equal(stats_pruned, stats_both)
