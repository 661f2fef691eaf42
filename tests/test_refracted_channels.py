"""The colour channels of a point light refracted into a many-faced convex shape share each segment's
faces, their cull, their edge breaks and the breaks' isolation for the bound (media/slab.py
`_faces_quad`, `faces_quadrature`, `channel_break_errors`: none reads a channel's coefficients), where
their integrals end at the same depth; a channel whose exp(-sigma_t x) underflows first ends sooner
and takes its own. Each channel's value and bound are those of a grey medium with its coefficients,
bit for bit."""
import numpy as np
import trimesh

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from .conftest import to_toml

SIGMA_A = [0.2, 500.0, 0.05]  # the second channel underflows 745 / 500.4 = 1.49 into the ball: its own end
SIGMA_S = [0.5, 0.4, 0.3]


def ball(sigma_a, sigma_s):
    mesh = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
    return {"camera": {"position": [0.3, 0.4, 3.2], "look_at": [0.0, 0.0, 0.0], "fov": 20.0, "width": 3,
                       "height": 2, "spp": 1},
            "medium": {"sigma_a": 0.01},
            "shape": [{"primitive": "triangles", "vertices": mesh.vertices.tolist(), "faces": mesh.faces.tolist(),
                       "interior": {"sigma_a": sigma_a, "sigma_s": sigma_s, "phase": {"type": "hg", "g": 0.3},
                                    "ior": 1.5}}],
            "light": [{"type": "point", "position": [0.6, 2.0, -2.2], "intensity": 8.0}]}


def image(scene):
    return render(prepare(scene_from_text(to_toml(scene), "ball")), "quadrature", {"rtol": 1e-6},
                  RenderOptions(threads=1))


def test_each_channel_is_its_grey_medium():
    rgb = image(ball(SIGMA_A, SIGMA_S))
    assert np.all(rgb.image > 0.0) and np.all(np.isfinite(rgb.error_bound))
    for c in range(3):
        grey = image(ball([SIGMA_A[c]] * 3, [SIGMA_S[c]] * 3))
        assert np.array_equal(rgb.image[..., c], grey.image[..., c])
        assert np.array_equal(rgb.error_bound[..., c], grey.error_bound[..., c])
