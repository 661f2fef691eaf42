"""A spot light in a glass globe with fog outside, rendered: tests/test_globe_fog.py's scene (8 x 6: the globe on a
floor, fog around it) with tests/test_lamp_in_glass.py's SPOT inside, its light refracted out into the fog
(interiors/held.py `held_airlight`, media/sphere_refraction.py `out_of_sphere`, cut where a segment crosses the band
edges' rays out: `out_edge_cuts`) and onto the floor.

The twin is stored per pixel by tests/make_globe_twins.py (tests/data/globe_twins.json "pixels"): tests/
test_lamp_in_globe.py `twin`'s pixel (the floor lit through the glass seen straight, in the globe's mirror and
through it; the globe's inside) plus tests/test_globe_fog.py `fog_pixel`'s air-light (30-digit paths out, quad_vec
at epsrel 1e-12 between the twin's own crossings of the band edges, `band_cuts`), and that air-light alone; one
pixel is recomputed live. The fog's part of the render is the fog scene's image less the one without it (the same
extinction outside: the fog only adds its in-scattering)."""
import json

import numpy as np
import pytest

from . import oracle
from .test_globe_bounds import TWINS, band_cuts
from .test_globe_fog import FOG, fog_pixel
from .test_lamp_in_glass import CAMERA, SPOT
from .test_lamp_in_globe import floor_radiance, scene
from .test_light_inside import image

LIVE = (4, 3)  # (row, column): the floor beside the globe, its fog lit by the spot


@pytest.fixture(scope="module")
def stored():
    """The twin's pixels and their air-light (H, W, 3)."""
    twin = json.loads(TWINS.read_text())["pixels"]["spot"]
    return np.array(twin["pixels"]), np.array(twin["air"])


def test_the_stored_twin_is_recomputed(stored):
    """Pixel LIVE's twin recomputed (its crossings bisected from 50 samples, not 200) equals the stored one within
    1e-12 (measured: bit for bit), and the fog is lit by the spot on enough pixels for the comparisons below to test
    it: on 11 pixels of 48, at least 10 % of the pixel on 2 (the whole of one)."""
    pixels, air = stored
    j, i = LIVE
    o, d = oracle.camera_ray(CAMERA, i, j)
    live = fog_pixel(SPOT, j, i, 1e-12, lambda o, d, t: band_cuts(SPOT, o, d, t, samples=50))
    assert np.all(np.abs(live - air[j, i]) <= 1e-12 * air[j, i]), live / air[j, i] - 1.0
    assert np.all(np.abs(live + floor_radiance(SPOT, o, d) - pixels[j, i]) <= 1e-12 * pixels[j, i])
    lit = (air > 0.0).all(axis=2)
    assert lit.sum() >= 10 and (air[..., 1] > 0.1 * pixels[..., 1]).sum() >= 2, (lit.sum(), air[..., 1] / pixels[..., 1])


@pytest.mark.parametrize("rtol, within", [(1e-6, 1e-5), (1e-10, 1e-9)])
def test_quadrature_against_the_twin(stored, rtol, within):
    """quadrature (no volumetric shadows: the floor is another shape) within `within` of the twin on every pixel
    (measured 2.1e-14 at both), 0 where the twin is; the fog's part alone (the fog scene less the bare one) within
    `within` of the twin's air-light (measured 4.4e-13: the difference's rounding), 0 where the spot does not light
    the fog; the bound finite, never exceeded (measured at most 6.8e-3 of it) and not vacuous (median at most 10
    rtol of the value: 4.6e-9 and 2.8e-12, the floor's closed form dominating; at most 1.1 and 16 rtol)."""
    pixels, air = stored
    fog = image(scene(SPOT, FOG), "quadrature", {"rtol": rtol}, shadows=False)
    bare = image(scene(SPOT), "quadrature", {"rtol": rtol}, shadows=False)
    err = np.abs(fog.image - pixels)
    assert np.all(err <= within * pixels), np.max(err / np.maximum(pixels, 1e-300))
    part = fog.image - bare.image
    assert np.all(np.abs(part - air) <= within * air), np.max(np.abs(part - air) / np.maximum(air, 1e-300))
    bound, lit = fog.error_bound, pixels > 0.0
    assert np.all(np.isfinite(bound)) and np.all(err <= bound), np.max(err / bound)
    assert np.median(bound[lit] / pixels[lit]) <= 10.0 * rtol and np.all(bound[lit] <= 1e3 * rtol * pixels[lit])
