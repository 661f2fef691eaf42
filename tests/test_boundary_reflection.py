"""The mirror reflection of a refractive interior's boundary (bounded.cross, bounded.combine): a camera ray that
meets the boundary from outside also brings what the mirrored ray sees, times Fresnel's
reflectance for unpolarised light, here written from the Fresnel equations: a slab of black glass
(ior 1.5, absorbing so strongly that nothing comes back through it) under a uniform sky shows the
sky times R(theta) on every pixel, 4 % looking straight down and rising toward 1 at grazing
incidence; index-matched boundaries reflect nothing.
"""
from __future__ import annotations

import math

import numpy as np

from raytrace.camera import generate_rays
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import load_scene

from .conftest import to_toml

SKY = np.array([0.2, 0.4, 0.8])


def fresnel_reflectance(cos_i: float, n: float) -> float:
    """(Rs + Rp) / 2 from air into index n (1 on total reflection)."""
    sin_t = math.sqrt(max(0.0, 1.0 - cos_i * cos_i)) / n
    if sin_t >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin_t * sin_t)
    rs = (cos_i - n * cos_t) / (cos_i + n * cos_t)
    rp = (cos_t - n * cos_i) / (cos_t + n * cos_i)
    return 0.5 * (rs * rs + rp * rp)


def glass(tmp_path, ior):
    sc = {"name": "black glass", "background": {"radiance": SKY.tolist()},
          "camera": {"position": [0.0, 1.0, 2.0], "look_at": [0.0, -1.0, -1.5], "fov": 70.0, "width": 12,
                     "height": 10, "spp": 1},
          "light": [{"type": "point", "position": [0.0, 3.0, 0.0], "intensity": 1.0}],
          "shape": [{"primitive": "box", "min": [-100.0, -50.0, -100.0], "max": [100.0, 0.0, 100.0],
                     "interior": {"sigma_a": 1e3, "sigma_s": 0.0, "ior": ior}}]}
    (tmp_path / "s.toml").write_text(to_toml(sc))
    return prepare(load_scene(tmp_path / "s.toml"))


def test_black_glass_mirrors_the_sky_by_fresnel(tmp_path):
    prep = glass(tmp_path, 1.5)
    img = render(prep, "quadrature", {}, RenderOptions(threads=1)).image
    cam = prep.scene.camera
    _, d = generate_rays(cam)
    d = d.reshape(cam.height, cam.width, 3)
    down = d[..., 1] < 0.0
    assert down.sum() >= 60 and (~down).sum() >= 10
    want = np.array([[fresnel_reflectance(-d[j, i, 1], 1.5) if down[j, i] else 1.0 for i in range(cam.width)]
                     for j in range(cam.height)])[..., None] * SKY
    np.testing.assert_allclose(img, want, rtol=1e-9, atol=0.0)
    r = want[down][:, 0] / SKY[0]
    assert r.min() < 0.06 and r.max() > 0.3  # steep and grazing rays


def test_index_matched_boundaries_reflect_nothing(tmp_path):
    img = render(glass(tmp_path, 1.0), "quadrature", {}, RenderOptions(threads=1)).image
    cam = glass(tmp_path, 1.0).scene.camera
    _, d = generate_rays(cam)
    down = d.reshape(cam.height, cam.width, 3)[..., 1] < 0.0
    assert np.all(img[down] < 1e-12)
