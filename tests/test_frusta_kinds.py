"""The volumetric shadows' kernels compiled per kind of light (shadows/frusta.py `_by_kind`): the
kernel a scene with point lights only uses (the sun's branches pruned), the one a scene with suns
only uses (the point light's pruned) and the one with both kinds' code (the kind at run time) give
the same texel lists and the same lit pieces, bit for bit, on a random triangle soup under a point
light and a sun, for segments from random points in random directions (some ending in the soup's
midst, some unbounded)."""
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


def test_each_kind_alone_and_both_kinds_give_the_same_pieces():
    rng = np.random.default_rng(11)
    tris = soup(rng)
    frame = np.array([[0.3, 0.2, 0.1], [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    axis = np.array([0.3, -1.0, 0.2])
    alone = [frusta._light_bins(tris, frame, False, 16, 1e-6, frusta.REL * 10),
             frusta.sun_bins(tris, axis, 1e-6, 10.0, 16)]
    both = [frusta._light_bins(tris, frame, False, 16, 1e-6, frusta.REL * 10, mixed=True),
            frusta.sun_bins(tris, axis, 1e-6, 10.0, 16, mixed=True)]
    for a, b in zip(alone, both):
        for name in ("planes", "signs", "start", "tri", "lb", "cover", "cover_depth", "grid", "frame"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
    for li in (0, 1):
        segs = segments(rng, 2000, li)
        stats_alone, stats_both = np.zeros(len(frusta.STATS_NAMES)), np.zeros(len(frusta.STATS_NAMES))
        got_alone = frusta.lit_pieces(segs, [alone[li]] * 2, 10.0, stats_alone)  # one kind
        got_both = frusta.lit_pieces(segs, both, 10.0, stats_both)  # both kinds
        assert 0 < stats_alone[frusta.ST_FRUSTA] and 0 < stats_alone[frusta.ST_DARK]  # shadows were found
        assert len(got_alone[0]) > len(segs.length) // 2
        for x, y in zip(got_alone, got_both):
            assert np.array_equal(x, y)
        assert np.array_equal(stats_alone, stats_both)
