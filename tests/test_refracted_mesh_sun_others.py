"""The sun's refracted beams in a convex refractive shape of more face planes than the index-matched
kernel's KERNEL_PLANES (the 320-face glass icosphere of tests/test_refracted_mesh_sun.py), attenuated by
another, index-matched interior on their entry points' way to the sun (interiors/rows.py `_face_beams`
with `_other_interiors(..., many=True)`: shadows/through_others.py on each beam's face plane): the dense
absorbing box of tests/test_beams_through_others.py above part of the ball. Before, these beams were not
attenuated and the bound was infinite.

The twin uses the geometry alone: tests/test_refracted_mesh_sun.py's (each triangle's beam by Snell and
Fresnel by angles, its lit interval by barycentric coordinates, which are affine in x) times
exp(-kt_B c_B), c_B the chord of the path from the entry point Y(x) = p + x w + s(x) u toward the sun
through the dense box by a slab test (tests/test_beams_through_others.py `dense_chord`); Y is affine in
x, so scipy quad is cut where that path meets an edge of the box (solved from Y's line) and where the
faces it crosses change (bisected).
"""
import numpy as np

from .test_beams_through_others import DENSE, HI_B, LO_B, dense_chord
from .test_refracted_beams import switches
from .test_refracted_mesh_faces import triangles
from .test_refracted_mesh_sun import OUTSIDE, SUN, ball, check, sun_segment, twin
from .test_through_others import edge_crossings

TOWARD_SUN = -np.array(SUN["direction"], float) / np.linalg.norm(SUN["direction"])
KT_B = np.array(DENSE["sigma_a"], float)


def kinks(Y0, line, d):
    """The x in (0, d) where the path from Y0 + x line toward the sun meets an edge of the dense box or
    changes the faces it crosses."""
    return (edge_crossings(Y0, line, TOWARD_SUN, LO_B, HI_B, d)
            + switches(Y0, line, d, lambda Y: str(dense_chord(Y, TOWARD_SUN)[1])))


def dense_segment(scene, geometry, p, w, ell):
    return sun_segment(scene, geometry, p, w, ell,
                       through=(lambda Y: np.exp(-KT_B * dense_chord(Y, TOWARD_SUN)[0]), kinks))


def test_a_dense_box_attenuates_the_beams_of_a_320_face_ball():
    """Volumetric shadows: quadrature (rtol 1e-6) and analytic (the beams through the box by QUAD,
    counted handed) within 1e-6 of the twin with the dense box on every pixel (8.6e-11); their bounds
    finite, above the error, median at most 10 rtol of the value (1.1e-6 and 4.4e-9); not vacuous: the
    box darkens some pixel by more than 5 % (6 %) against the twin without it (before, these beams went
    unattenuated and the bound was infinite)."""
    scene = ball(OUTSIDE, SUN)
    scene["shape"].append({"primitive": "box", "min": LO_B.tolist(), "max": HI_B.tolist(), "interior": DENSE})
    geometry = triangles(scene)
    ref = twin(scene, geometry, dense_segment)
    free = twin(scene, geometry, sun_segment)
    assert np.max(1.0 - ref[..., 1] / free[..., 1]) > 0.05, np.max(1.0 - ref[..., 1] / free[..., 1])
    for method, params in (("quadrature", {"rtol": 1e-6}), ("analytic", {})):
        res = check(scene, ref, method, params, 1e-6, 1e-5, shadows=True)
        print(method, "largest relative error", np.max(np.abs(res.image - ref) / ref),
              "median bound / value", np.median(res.error_bound / ref))
