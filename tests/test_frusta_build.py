"""The volumetric shadows' texel lists (shadows/frusta.py) built without a per-texel sort: each
list ascending in depth lower bound with nothing behind its texel's cover, and the heapsort of
a segment's shadow intervals against NumPy's sort."""
import numpy as np

from raytrace.shadows import frusta


def test_heapsort_pairs_matches_numpy_sort():
    rng = np.random.default_rng(5)
    for n in [*range(12), 50, 333, 1000]:
        for ties in (False, True):
            a = rng.integers(0, 4, n).astype(float) if ties else rng.normal(size=n)
            b = 10.0 * a + 1.0  # b travels with a
            x, y = a.copy(), b.copy()
            frusta._heapsort_pairs(x, y)
            assert np.array_equal(x, np.sort(a)) and np.array_equal(y, 10.0 * x + 1.0)


def test_texel_lists_ascending_and_pruned_by_cover():
    rng = np.random.default_rng(3)
    centres = rng.uniform(-3, 3, (300, 1, 3))
    tris = centres + rng.normal(size=(300, 3, 3)) * 0.4
    frame = np.array([[0.3, 0.2, 0.1], [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    for bins in (frusta._light_bins(tris, frame, False, 16, 1e-6, frusta.REL * 10),
                 frusta.sun_bins(tris, np.array([0.3, -1.0, 0.2]), 1e-6, 10.0, 16)):
        assert len(bins.tri) and bins.start[-1] == len(bins.tri)
        for k in range(len(bins.start) - 1):
            seg = slice(bins.start[k], bins.start[k + 1])
            assert np.all(np.diff(bins.lb[seg]) >= 0.0)  # ascending
            assert np.all(bins.lb[seg] <= bins.cover_depth[k])  # nothing wholly behind the cover
            assert len(np.unique(bins.tri[seg])) == len(bins.tri[seg])
