"""quadrature's error bound for point and spot light refracted into a convex refractive shape where
occluders cast volumetric shadows into it (shadows/fermat_legs.py, "Spans"; docs/error_bounds.md,
"Point and spot light in refractive shapes"): the water box under a lamp and the glass block beside a
spot of tests/test_refracted_shadows.py, each with a black plate outside shadowing the outside legs
and one inside shadowing the inside legs, against that file's twin (Fermat's path by scipy's own
minimisation, the plates by ray-plane tests, the shadow breaks bisected on the lit indicator, scipy
quad_vec between them): the geometry alone.

Before the spans the bound was inf on every segment cut by a plate's shadow (most pixels of both
images)."""
import numpy as np
import pytest

from raytrace.interiors.shapes import blockers, convex_planes
from raytrace.interiors.shapes import measured_plane_errors
from raytrace.rendering.renderer import prepare
from raytrace.scene.format import scene_from_text
from raytrace.shadows.fermat_legs import SPAN_WIDTH, lit_pieces_of_point

from . import oracle
from .conftest import to_toml
from .test_refracted_beams import plate_hit, plate_shape
from .test_refracted_point_bounds import assert_bound
from .test_refracted_point_light import FACES, GLASS, WATER, camera_entry, switches
from .test_refracted_shadows import BOX, CAM, PLATES, clear, fermat, image, on_face, shadowed_scene, twin_pixel


@pytest.fixture(scope="module", params=[WATER, GLASS], ids=["water_lamp_above", "glass_spot_beside"])
def case(request):
    scene = shadowed_scene(request.param)
    twin = np.array([[twin_pixel(scene, i, j) for i in range(CAM["width"])] for j in range(CAM["height"])])
    return scene, twin


@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_the_bound_holds_and_is_not_vacuous(case, rtol):
    """Finite on every pixel (inf before on the segments a plate's shadow cuts), never below the
    error, and its median at most 10 rtol of the value."""
    scene, twin = case
    assert np.count_nonzero(twin[..., 1] > 0.0) >= 30
    assert_bound(image(scene, "quadrature", {"rtol": rtol}), twin, rtol)


def test_the_bound_is_close_enough_to_fail(case):
    """At rtol 1e-12 the bound still holds; in the water box the error left (a pixel whose
    refraction point crosses a face's edge near its segment's end: the face test's tolerance) reaches
    a tenth of it, so a bound ten times too small fails there. (The spans' share is not that tight:
    the breaks the search takes are within a few ulps of the twin's, their bound charges the
    worst-case rounding of the refraction point.)"""
    scene, twin = case
    res = image(scene, "quadrature", {"rtol": 1e-12})
    ratio = np.abs(res.image - twin) / res.error_bound
    assert np.all(ratio <= 1.0), np.max(ratio)
    if scene["name"] == "water_box":
        assert np.max(ratio) > 0.1, np.max(ratio)


@pytest.mark.parametrize("scene", [WATER, GLASS], ids=["water_lamp_above", "glass_spot_beside"])
def test_every_shadow_switch_lies_in_a_span(scene):
    """On every pixel's segment (the twin's own entry point and direction) and every face the light
    is outside of, each x where the twin's shadow indicator (both legs clear of the plates) switches
    while the refraction point lies on the face (bisected between 200 samples) lies within a span of
    `lit_pieces_of_point`; every segment's spans are known, and they are narrow."""
    scene = shadowed_scene(scene)
    prep = prepare(scene_from_text(to_toml(scene), scene["name"]))
    planes, mask, dplanes = convex_planes(prep, 0), blockers(prep), measured_plane_errors(prep, 0)
    outer, inner_plate = PLATES[scene["name"]]
    eta = scene["shape"][0]["interior"]["ior"]
    L = np.array(scene["light"][0]["position"], float)
    found, widths = 0, []
    for j in range(CAM["height"]):
        for i in range(CAM["width"]):
            entry = camera_entry({**scene, "camera": CAM}, i, j, eta)
            if entry is None:
                continue
            _, p, w, _, _ = entry
            ell = min(oracle.box_exit(p, w, -BOX * np.ones(3), BOX * np.ones(3))[0], plate_hit(p, w, inner_plate))
            for n in FACES:
                if n @ L <= BOX:
                    continue
                f = int(np.argmax(planes[:, :3] @ n))

                def shade(x):
                    R = fermat(p + x * w, L, n, BOX, eta)[0]
                    return clear(L, R, (outer,)) and clear(R, p + x * w, (inner_plate,))

                *_, (seg, lo, hi, sure) = lit_pieces_of_point(prep, 0, planes, mask, 0, f, p[None], w[None],
                                                              np.array([ell]), dplanes)
                assert sure[0]
                widths += list(hi - lo)
                for x in switches(p, w, ell, shade, 200):
                    R = fermat(p + x * w, L, n, BOX, eta)[0]
                    if not on_face(R, n):
                        continue
                    assert np.any((lo <= x) & (x <= hi)), (i, j, f, x, lo, hi)
                    found += 1
    assert found >= 10, found
    assert max(widths) <= SPAN_WIDTH * prep.accel.scale and np.median(widths) < 1e-10, (max(widths),
                                                                                          np.median(widths))


def test_segments_whose_breaks_are_not_located_are_counted():
    """A plate in the lamp's own horizontal plane, beside it toward the water box: every leg starts on
    the plate's plane (within the segment-triangle test's tolerance), so no segment's shadow breaks are
    located and the bound is inf on every pixel; the statistics count the segments. Without the plate the
    bound is finite and nothing is counted."""
    small = {**WATER, "camera": {**WATER["camera"], "width": 3, "height": 3}}
    key = "inside: segments with shadow breaks not located (bound inf)"
    beside = image({**small, "shape": WATER["shape"] + [plate_shape((1, 2.2, (1.0, -1.3), (1.45, 1.1)))]}, "quadrature",
                   {"rtol": 1e-6})
    assert beside.image.min() > 0.0 and np.all(np.isinf(beside.error_bound))
    assert beside.stats[key] == 9, beside.stats
    clear = image(small, "quadrature", {"rtol": 1e-6})
    assert np.all(np.isfinite(clear.error_bound)) and clear.stats[key] == 0, (clear.error_bound, clear.stats)
