"""The planes' errors that every convex kernel's bound takes (interiors/shapes.py `measured_plane_errors`):
the hull keeps one plane for faces within 1e-9 of each other, so a face whose corners lie a little off
one plane (here the top of an index-matched box, one corner raised 4e-10) is integrated on a plane up
to that far from its triangles. The twin measures, from the triangles as written (numpy, not the
renderer's arrays), each triangle's largest vertex offset from the hull plane its own normal is nearest;
the errors the kernels take must cover it, for an index-matched shape as for a refractive one. (Before,
an index-matched shape's kernels took the rounding of one triangle's plane alone, ~1e-12: too small.)"""
import numpy as np
import pytest

from raytrace.interiors import shapes
from raytrace.rendering.renderer import prepare
from raytrace.scene.format import scene_from_dict

RAISED = 4e-10


def _box():
    """A unit cube's 12 triangles (outward windings), the corner (1, 1, 1) raised by RAISED."""
    v = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])
    v[7, 2] += RAISED
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    faces = [[a, b, c] for a, b, c, d in quads] + [[a, c, d] for a, b, c, d in quads]
    return v, np.array(faces)


@pytest.mark.parametrize("ior", [1.0, 1.33])
def test_the_measured_errors_cover_the_faces_off_their_plane(ior):
    v, f = _box()
    scene = scene_from_dict({
        "camera": {"position": [0.0, 0.5, 5.0], "look_at": [0.0, 0.0, 0.0], "width": 4, "height": 3, "spp": 1},
        "medium": {"sigma_a": 0.0, "sigma_s": 0.0},
        "light": [{"type": "point", "position": [0.0, 4.0, 0.0], "intensity": 1.0}],
        "shape": [{"primitive": "triangles", "vertices": v.tolist(), "faces": f.tolist(),
                   "interior": {"sigma_a": 0.1, "sigma_s": 0.2, "ior": ior}}]}, "raised box")
    prep = prepare(scene)
    planes = shapes.hull_planes(prep, 0)
    assert planes is not None and len(planes) == 6  # the raised corner's two triangles share one plane
    tris = v[f]
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    n /= np.linalg.norm(n, axis=1)[:, None]
    nearest = np.argmax(n @ planes[:, :3].T, axis=1)
    offsets = np.abs(np.einsum("tvk,tk->tv", tris, planes[nearest, :3]) - planes[nearest, 3, None]).max(axis=1)
    dn, dc = shapes.measured_plane_errors(prep, 0)
    assert offsets.max() > 0.4 * RAISED  # the twin sees the raised corner
    assert dc >= offsets.max()
    assert dn >= np.abs(n - planes[nearest, :3]).max()
    assert shapes.plane_errors(prep, 0)[1] < offsets.max()  # the rounding of one plane alone is not enough
