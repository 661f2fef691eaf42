"""Kernels that took over NumPy expressions of the area lights' pilot and penumbrae, each against those
expressions written out here, bit for bit (docs/area_lights.md, "Time to 1e-2 against Mitsuba 3")."""
from __future__ import annotations

import numpy as np
import pytest

from raytrace.lights import cubature


def numpy_half_line_distances(points, origins, dirs):
    """The former NumPy `cubature.half_line_distances`: per point and half-line |rel - max(rel . d, 0) d|."""
    rel = (points[:, None, :] - origins[None]).reshape(-1, 3)
    d = np.broadcast_to(dirs, (len(points),) + dirs.shape).reshape(-1, 3)
    t = np.maximum(np.einsum("ij,ij->i", rel, d), 0.0)
    dist = np.linalg.norm(rel - t[:, None] * d, axis=1).reshape(len(points), -1)
    return np.minimum(np.full(len(origins), np.inf), dist.min(axis=0))


@pytest.mark.parametrize("seed", range(4))
def test_half_line_distances_as_numpy(seed):
    rng = np.random.default_rng(seed)
    if seed == 0:  # a unit quad's probe points
        points = cubature.probe_points(lambda u, v: (np.stack([u - 0.5, np.full_like(u, 2.0), v - 0.5], axis=1),))
    else:
        points = rng.normal(size=(int(rng.integers(1, 400)), 3)) * rng.uniform(0.01, 100.0)
    origins = rng.normal(size=(700, 3)) * rng.uniform(0.1, 10.0)
    dirs = rng.normal(size=(700, 3))
    dirs[::7, int(rng.integers(3))] = 0.0  # zero components
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    origins[5] = points[0]  # a half-line from a point, one through it
    dirs[6] = (points[-1] - origins[6]) / np.linalg.norm(points[-1] - origins[6])
    dirs[9] = np.nan
    got, want = cubature.half_line_distances(points, origins, dirs), numpy_half_line_distances(points, origins, dirs)
    assert np.isnan(got[9]) and np.isnan(want[9])
    assert got[5] == 0.0 and got[6] < 1e-12
    assert np.array_equal(got, want, equal_nan=True)
