"""The environment camera's rays with their sines and cosines remembered (camera._ray_kernel's memo)
are, bit for bit, the module's formula evaluated afresh for every ray in Python's own arithmetic."""
import math

import numpy as np

from raytrace import camera
from raytrace.scene.format import Camera


def fresh(cam, x, y):
    """One environment ray's direction through the image point (x, y), every sine and cosine computed."""
    forward, right, up = (v.tolist() for v in camera.basis(cam))
    phi, theta = (2.0 * math.pi) * (x / cam.width - 0.5), math.pi * y / cam.height
    st, cp, sp, ct = math.sin(theta), math.cos(phi), math.sin(phi), math.cos(theta)
    d = [st * (cp * f + sp * r) + ct * u for f, r, u in zip(forward, right, up)]
    length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    return [c / length for c in d]


def test_remembered_trig_is_each_rays_own():
    cam = Camera("environment", np.array([1.0, 2.0, 3.0]), np.array([0.3, 1.0, -2.0]), np.array([0.0, 1.0, 0.0]),
                 60.0, 512, 256, 5)  # 5 spp: R2 offsets, each sample its own x and y
    # a tile's pattern (columns cycling, rows repeated), columns 3 and 34 sharing a slot (TRIG_SLOTS = 31), a
    # column seen again after others took its slot, and scattered pixels
    xs = np.array([3, 131, 259, 387, 3, 131, 259, 387, 34, 3, 34, 34, 65, 3, 511, 0, 0, 200])
    ys = np.array([7, 7, 7, 7, 8, 8, 8, 8, 8, 8, 9, 9, 9, 10, 255, 0, 0, 100])
    assert 34 % camera.TRIG_SLOTS == 3 % camera.TRIG_SLOTS
    off = camera.sample_offsets(cam.spp)
    o, d = camera.pixel_rays(cam, ys, xs)
    want = [fresh(cam, x + off[s, 0], y + off[s, 1]) for x, y in zip(xs, ys) for s in range(cam.spp)]
    assert np.array_equal(d, np.array(want))
    assert np.array_equal(o, np.broadcast_to(cam.position, o.shape))
    whole = camera.generate_rays(cam, slice(250, 256), slice(0, 512), slice(2, 3))[1]
    assert np.array_equal(whole, np.array([fresh(cam, i + off[2, 0], j + off[2, 1]) for j in range(250, 256)
                                           for i in range(512)]))
