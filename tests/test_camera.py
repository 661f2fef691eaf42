"""Camera rays against the SCENE_FORMAT.md formulas (re-derived in tests/oracle.py)."""
import math

import numpy as np
import pytest

from raytrace.camera import generate_rays, sample_offsets
from raytrace.scene.format import Camera

from . import oracle


def cam(kind, spp=1, **kw):
    d = dict(type=kind, position=[1.0, 2.0, 3.0], look_at=[0.0, 1.0, -2.0], up=[0.0, 1.0, 0.0], fov=50.0,
             width=7, height=5, spp=spp)
    d.update(kw)
    return d


def to_camera(d):
    return Camera(d["type"], np.array(d["position"], float), np.array(d["look_at"], float), np.array(d["up"], float),
                  d["fov"], d["width"], d["height"], d["spp"])


@pytest.mark.parametrize("kind", ["perspective", "environment"])
@pytest.mark.parametrize("spp", [1, 4, 9, 3])
def test_rays_follow_the_documented_formulas(kind, spp):
    c = cam(kind, spp)
    o, d = generate_rays(to_camera(c))
    offs = sample_offsets(spp)
    k = 0
    for j in range(c["height"]):
        for i in range(c["width"]):
            for s, t in offs:
                po, pd = oracle.camera_ray(c, i, j, s, t)
                np.testing.assert_allclose(o[k], po, rtol=0, atol=1e-15)
                np.testing.assert_allclose(d[k], pd, rtol=0, atol=1e-14)
                k += 1


def test_sample_pattern():
    np.testing.assert_array_equal(sample_offsets(1), [[0.5, 0.5]])
    np.testing.assert_allclose(np.sort(sample_offsets(4)[:, 0]), [0.25, 0.25, 0.75, 0.75])
    for n in (2, 3, 5, 7, 16):
        s = sample_offsets(n)
        assert s.shape == (n, 2) and np.all((s >= 0) & (s < 1))
        assert len(np.unique(s, axis=0)) == n


def test_environment_axes():
    """Centre column looks forward, 3/4 of the width looks right, the top row looks up."""
    c = to_camera(cam("environment", width=4, height=2, position=[0, 0, 0], look_at=[0, 0, -1]))
    _, d = generate_rays(c, slice(0, 2), slice(0, 4))
    d = d.reshape(2, 4, 3)
    # pixel i=1 (centre offset 0.5): phi = 2 pi (1.5/4 - 0.5) = -pi/4; theta = pi/4 for row 0
    phi, theta = -math.pi / 4, math.pi / 4
    fwd, right, up = np.array([0, 0, -1.0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    exp = math.sin(theta) * (math.cos(phi) * fwd + math.sin(phi) * right) + math.cos(theta) * up
    np.testing.assert_allclose(d[0, 1], exp, atol=1e-15)
    assert d[0, 1] @ up > 0 and d[1, 1] @ up < 0
