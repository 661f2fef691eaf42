"""The bundled feature scenes show their feature, in numbers rather than looks: stage's column casts a
dark shaft into the key light's beam (only with volumetric shadows), the ocean's floor darkens with
depth under a sky, box_room's walls have the colours they are given. Each renders small.

Pixels are picked by geometry: the pixel whose camera ray points closest to a 3D point of the scene.
"""
import numpy as np
import pytest

import raytrace
from raytrace.camera import generate_rays

from .test_boundary_reflection import fresnel_reflectance

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def small(name, width, height):
    """The bundled scene at a small size, one sample per pixel, and its camera's rays (row-major)."""
    scene = raytrace.load(name, [f"camera.width={width}", f"camera.height={height}", "camera.spp=1"])
    o, d = generate_rays(scene.camera)
    return scene, o, d


def pixel_toward(o, d, width, point):
    """(row, column) of the ray that points closest to `point`."""
    to = np.asarray(point, float) - o
    cos = np.einsum("ij,ij->i", d, to) / (np.linalg.norm(d, axis=1) * np.linalg.norm(to, axis=1))
    return divmod(int(np.argmax(cos)), width)


def test_stage_column_casts_a_dark_shaft_into_the_key_beam():
    """A point on the key light's axis beyond the column (80 % of the way to the floor; the column's
    centre is at 61 %) is in its shadow; points 6.5 degrees to either side of the axis, seen from
    the light, are in the beam beside it (beyond the column's angular radius of 4.2 degrees and
    within the 10 degree cone, where the smoothstep still gives 85 % of the intensity). The pixels that
    look at them: with volumetric shadows the shaft's pixel is at least 1.5 times darker than the
    dimmer side; without them the haze there glows, at least 90 % as bright."""
    w, h = 120, 80
    scene, o, d = small("stage", w, h)
    key = scene.lights[0]
    p, target = np.asarray(key.position, float), np.array([0.97, 0.6, 1.24])  # the key light's look_at
    axis = target - p
    shaft = p + 0.8 * axis
    side = np.cross(axis, [0.0, 1.0, 0.0])
    side *= np.linalg.norm(shaft - p) * np.tan(np.radians(6.5)) / np.linalg.norm(side)
    pixels = [pixel_toward(o, d, w, x) for x in (shaft, shaft + side, shaft - side)]
    assert len(set(pixels)) == 3
    lum = {}
    for shadows in (True, False):
        img = raytrace.render("stage", width=w, height=h, spp=1, threads=1, volumetric_shadows=shadows).array
        lum[shadows] = [float(img[r, c] @ LUMINANCE) for r, c in pixels]
    on, off = lum[True], lum[False]
    assert raytrace.load("stage").render["volumetric_shadows"] is True
    assert on[0] < min(on[1:]) / 1.5, on
    assert off[0] > 0.9 * min(off[1:]), off


def test_ocean_floor_darkens_with_depth_under_a_sky():
    """Rays that rise see the sky: exactly the background radiance (the outside is vacuum). Below the
    horizon the surface mirrors the sky by Fresnel's reflectance (tests/test_boundary_reflection.py's
    formula; the mirrored rays of the middle column rise to the sky, no post in their way): near the
    horizon the sea is mostly sky. What comes up through the surface (the pixel minus that reflection)
    falls row by row toward the horizon along the image's middle column, by more than 10 times, as the
    sea floor deepens away from the camera; the water is blue-green: red is the weakest channel
    wherever the floor lies deeper than 5 m."""
    w, h = 64, 40
    scene, o, d = small("ocean", w, h)
    img = raytrace.render("ocean", width=w, height=h, threads=1).array
    dy = d[:, 1].reshape(h, w)
    sky = dy > 0
    assert 0.1 < sky.mean() < 0.5
    np.testing.assert_array_equal(img[sky], np.broadcast_to(scene.background, img[sky].shape))
    col = w // 2
    rows = np.nonzero(dy[:, col] < 0)[0]  # top (horizon) to bottom (near)
    mirrored = np.array([fresnel_reflectance(-dy[r, col], 1.33) for r in rows])[:, None] * scene.background
    assert img[rows[0], col] @ LUMINANCE > 0.5 * scene.background @ LUMINANCE  # grazing: mostly sky
    up = img[rows, col] - mirrored
    assert np.all(up > 0.0)
    lum = up @ LUMINANCE
    assert np.all(np.diff(lum) > 0), lum
    assert lum[-1] > 10 * lum[0]
    # where the ray meets the floor (the plane through its corners), and how deep it is there
    a, c = np.array([-300.0, -0.4, 18.0]), np.array([300.0, -62.8, -400.0])  # scenes/ocean.toml's floor
    o0 = o.reshape(h, w, 3)[rows, col]
    t_surface = -o0[:, 1] / dy[rows, col]
    hit_surface = o0 + t_surface[:, None] * d.reshape(h, w, 3)[rows, col]
    # below the surface the ray is refracted; the floor's depth under the entry point bounds it from below
    depth_below_entry = -(a[1] + (hit_surface[:, 2] - a[2]) * (c[1] - a[1]) / (c[2] - a[2]))
    deep = depth_below_entry > 5.0
    assert deep.sum() >= 3
    px = up[deep]
    assert np.all(px[:, 0] < px[:, 1]) and np.all(px[:, 0] < px[:, 2])


@pytest.mark.parametrize("direction, channel", [((-1.0, 0.0, 0.0), 0), ((1.0, 0.0, 0.0), 1), ((0.0, 0.0, 1.0), 2)])
def test_box_room_walls_have_their_colours(direction, channel):
    """The environment camera looks at the left, right and front walls' centres at eye height: the
    red, green and blue walls' pixels have that channel strongest, by at least 1.5 times (the haze's
    neutral glow in front of them dilutes the reflectances' ratios of 4 and more)."""
    w, h = 64, 32
    scene, o, d = small("box_room", w, h)
    img = raytrace.render("box_room", width=w, height=h, threads=1).array
    r, c = pixel_toward(o, d, w, o[0] + 10.0 * np.array(direction))
    px = img[r, c]
    others = np.delete(px, channel)
    assert px[channel] > 1.5 * others.max(), px
