"""The glass torus of benchmarks/torus.py (a lamp's light refracted through every face of a non-convex mesh,
media/nonconvex_refraction.py) against a twin from the geometry alone: quadrature's bound is checked against
values that do not come from the renderer.

The twin (tests/refraction_twin.py `Glass`, stored by `python -m tests.make_torus_twins` in
tests/data/torus_twins.json: about 20 s a pixel) reads the OBJ's triangles; one pixel is recomputed live.
"""
import json

import numpy as np
import pytest

from benchmarks.torus import torus_scene
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render

from . import make_torus_twins as twins
from . import oracle
from .refraction_twin import tube_irradiance
from .test_nonconvex_refraction import ETA, transmittance
from .test_nonconvex_refraction import tube_irradiance as tube_by_differences

DATA = json.loads(twins.PATH.read_text())
LIVE = (4, 2)  # the quickest pixel to recompute (about 2 s)


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    scene = torus_scene(tmp_path_factory.mktemp("torus"), DATA["sections"], DATA["width"], DATA["height"], 1.5)[0]
    prep = prepare(scene)
    return {rtol: render(prep, "quadrature", {"rtol": rtol}, RenderOptions(threads=1)) for rtol in (1e-6, 1e-10)}


def test_the_twins_ray_tube_is_the_u_twins():
    """The twin's closed-form ray tube agrees with the U twin's central differences of the refracted rays' map on
    the torus's paths along pixel LIVE's stretch (the same index, 1.5)."""
    glass = twins.glass()
    assert glass.eta == ETA
    _, _, P, w, ell = glass.inside_stretch(*oracle.camera_ray(twins.CAMERA, *LIVE))
    checked = 0
    for x in np.linspace(0.05, 0.95, 7):
        X = P + x * ell * w
        for f, R, n in zip(*glass.fermat_points(X)):
            o, hl, k = np.linalg.norm(glass.lamp - R), float((glass.lamp - R) @ n), np.linalg.norm(R - X)
            ref = tube_by_differences(glass.lamp, R, n, k) / transmittance(hl / o, ETA)  # the U's has T in it
            assert abs(tube_irradiance(o, hl, k, ETA) / ref - 1) < 1e-8
            checked += 1
    assert checked >= 5


def test_the_stored_twin_is_the_twin():
    """One stored pixel recomputed from the geometry (to the twin's quad_vec tolerance, 1e-12)."""
    ref = next(p for p in DATA["pixels"] if (p["i"], p["j"]) == LIVE)
    value, cuts = twins.pixel(twins.glass(), *LIVE)
    np.testing.assert_allclose(value, ref["value"], rtol=1e-11)
    assert len(cuts) - 2 == ref["breaks"]


@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_quadrature_is_within_its_bound_of_the_twin(renders, rtol):
    """On the twin's pixels: the dark ones dark; every lit one within 10 rtol of the twin (its bound finite or not),
    within its bound where that is finite, the bound finite on most (measured at 1e-6: all but (8, 5), whose scan
    runs out of its budget; (4, 2) was inf before a node inside a cluster the scan left undecided added the
    cluster's jump to its bound) and not vacuous (median at most 10 rtol of the value). Before the twin split its search where a face is lit on a sliver between two changes, it missed a
    break 3e-8 of the segment wide at (4, 1) and was 1.6e-9 off, above quadrature's bound at 1e-10."""
    res = renders[rtol]
    lit = bounded = 0
    ratios = []
    for p in DATA["pixels"]:
        i, j, ref = p["i"], p["j"], np.array(p["value"])
        got, bound = res.image[j, i], res.error_bound[j, i]
        if not np.any(ref > 0.0):
            assert np.all(got == 0.0), (i, j, got)
            continue
        lit += 1
        assert np.all(ref > 0.0) and np.max(np.abs(got - ref) / ref) < 10 * rtol, (i, j, got, ref)
        if np.all(np.isfinite(bound)):
            bounded += 1
            assert np.all(np.abs(got - ref) <= bound), (i, j, np.abs(got - ref), bound)
            ratios.append(np.max(bound / ref))
    assert lit >= 12 and bounded >= lit - 2, (lit, bounded)
    assert np.median(ratios) <= 10 * rtol, np.median(ratios)
