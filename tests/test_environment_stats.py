"""What a render with an environment light counts and builds (rendering/renderer.py `_sample_by_sample`,
`shade_groups`, `seeded`): each pixel sample is shaded in passes (the other lights, then each group of the
environment's directions) sharing the camera rays' first hits.

- Its statistics count each camera ray once: the render's summary equals the one computed here from a single
  pass per pixel sample over all the lights at once (`shade_rays` on that sample's directions), summed over the
  pixels and samples; in fog (outside) and in a fog box in vacuum (the inside integrals' statistics), with and
  without volumetric shadows.
- A pixel sample's shadow frusta are built once: its passes' views (and the layers') share them.
"""
from __future__ import annotations

import numpy as np
import pytest

from raytrace import api
from raytrace.camera import pixel_rays
from raytrace.interiors import support
from raytrace.lights import environment
from raytrace.methods import resolve_params
from raytrace.rendering import renderer
from raytrace.shadows.frusta import STATS_NAMES

from .test_environment import ENV, FOG, GROUND, PLATE, scene

LAMP = {"position": [0.3, 2.0, 0.2], "intensity": 1.0}
CAMERA = {"position": [0.0, 0.6, 3.0], "look_at": [0.0, 0.4, 0.0], "fov": 40.0, "width": 4, "height": 3, "spp": 2}
BOX = {"primitive": "box", "min": [-0.5, 0.0, -0.5], "max": [0.5, 0.8, 0.5],
       "interior": {"sigma_a": 0.2, "sigma_s": 0.6, "ior": 1.0}}
SEED = 5


def fog():
    return scene([ENV, LAMP], medium=FOG, camera=CAMERA, shapes=[GROUND, PLATE])


def fog_box():
    return scene([ENV, LAMP], camera=CAMERA, shapes=[GROUND, PLATE, BOX])


def one_pass_summary(sc, name, given, shadows):
    """The summary's statistics of a render of `sc` (seed SEED) from one `shade_rays` per pixel sample over every
    light, that sample's environment directions (`renderer.seeded`), the camera rays' keys as the render's."""
    prep, method, cam = renderer.prepare(sc), renderer.get_method(name), sc.camera
    params = resolve_params(method, given, "test")
    ys, xs = np.divmod(np.arange(cam.width * cam.height), cam.width)
    totals = 0.0
    for s in range(cam.spp):
        o, d = pixel_rays(cam, ys, xs, slice(s, s + 1))
        keys = (ys * cam.width + xs).astype(np.uint64) * np.uint64(cam.spp) + np.uint64(s)
        view = renderer.seeded(prep, SEED, s, shadows)
        assert view is not prep  # the sample's own directions
        totals = totals + renderer.shade_rays(view, method, params, o, d, keys, SEED, shadows)[1]
    out = method.summarize(totals[:method.stats_size])
    if shadows:
        out.update({f"shadows: {k}": int(v) for k, v in zip(STATS_NAMES, totals[method.stats_size:])})
    out.update(support.summarize(prep, method, totals[-support.STATS_SIZE:], shadows))
    return out


@pytest.mark.parametrize("case, name, given, shadows", [
    (fog, "quadrature", {"rtol": 1e-6}, False),
    (fog, "quadrature", {"rtol": 1e-6}, True),
    (fog_box, "quadrature", {"rtol": 1e-6}, True),
], ids=["fog", "fog-shadows", "box-shadows"])
def test_statistics_count_each_camera_ray_once(case, name, given, shadows):
    """The render's statistics equal one pass's over all the lights (on main the inside ones were G + 1 = 3 times
    theirs: each pass counted every light)."""
    sc = case()
    img = api.render(sc, name, seed=SEED, threads=1, volumetric_shadows=shadows, **given)
    expected = one_pass_summary(sc, name, given, shadows)
    assert expected and {k: img.stats[k] for k in expected} == expected


def test_a_samples_passes_share_its_frusta():
    """With volumetric shadows a pixel sample's frusta are built once (`seeded`), not once per pass view (each
    a copy that built its own: 3 x the builds and the memory); the image is the same bits either way."""
    sc = fog()
    prep = renderer.prepare(sc)
    view = renderer.seeded(prep, SEED, 1, True)
    frusta = view._frusta
    assert frusta is not None and len(frusta) == len(view.lights)
    passes = [view.view(~np.any(environment.groups(view.lights), axis=0), emission=True)]
    passes += [view.view(keep) for keep in environment.groups(view.lights)]
    assert all(p.frusta() is frusta for p in passes)
    assert renderer.seeded(prep, SEED, 1, True) is view
