"""Bounded memory of volumetric shadows (issue 8, defect 5): `--steps 100000 --volumetric-shadows`
runs in memory that depends on neither the step count nor the number of rays.

With `shadow_test = samples` (a shadow ray per medium sample) the points are made and traced in
chunks of at most POINTS_PER_CHUNK (visibility.shadowed_airlight). Before that chunking (5a2a706) a
tile's rays were cut into batches of 1024 rays only, each batch holding arrays of rays x lights x
steps x channels points: this test's 8 x 8 render peaked at 1373 MiB of numpy arrays (tracemalloc,
nearly 5 x the bound below; a full 1024-ray batch would have needed ~22 GiB); chunked it peaks at
~120 MiB. The default lit-interval search (`shadow_test = intervals`) never holds the march's points.
"""
import tracemalloc

import numpy as np
import pytest

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text
from raytrace.shadows.shadow_rays import POINTS_PER_CHUNK

from .conftest import box_room, to_toml

CAMERA = {"position": [0.0, 0.0, 3.5], "look_at": [0.0, 0.0, -1.0], "fov": 80.0, "width": 8, "height": 8, "spp": 1}
LIGHT = [{"position": [0.0, 1.5, -1.0], "intensity": 20.0}]
STEPS = 100_000
# one chunk's sample arrays: positions (3 channels x 3 coordinates) and weights (3 channels) in
# float64; the shadow rays' temporaries are a few more arrays of that order
CHUNK_BYTES = POINTS_PER_CHUNK * (3 * 3 + 3) * 8
BOUND = 6 * CHUNK_BYTES  # 288 MiB


@pytest.mark.parametrize("shadow_test", ["samples", "intervals"])
def test_volumetric_shadows_with_100000_steps_run_in_bounded_memory(shadow_test):
    scene = box_room(camera=CAMERA, light=LIGHT)
    prep = prepare(scene_from_text(to_toml(scene), "test"))
    params = {"steps": STEPS, "shadow_test": shadow_test}
    opts = RenderOptions(threads=1, volumetric_shadows=True)
    render(prep, "raymarch", dict(params, steps=4), opts)  # compile outside the trace
    points = CAMERA["width"] * CAMERA["height"] * len(LIGHT) * STEPS
    unchunked = points * (3 * 3 + 3) * 8  # what the sample arrays alone of one batch took before
    assert unchunked > 10 * CHUNK_BYTES
    tracemalloc.start()
    try:
        image = render(prep, "raymarch", params, opts).image
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert np.all(np.isfinite(image)) and np.all(image > 0.0)
    assert peak < BOUND, f"peak {peak / 2**20:.0f} MiB of arrays, bound {BOUND / 2**20:.0f} MiB"
