"""Smooth shading (a shape's `smooth`, shading.shading_normals): interpolated corner normals in the
surface term (the paper's eq. 5), the geometric normal kept for visibility and the terminator.

The twin: the exact sphere that the mesh of `segments` approximates, Lambertian (rho), lit by a point
light (I) in vacuum and seen by the camera: at the exact hit point x with the exact normal n,
L = rho / pi I max(0, n·wi) / d^2 (numpy only; a sphere does not shadow itself beyond n·wi <= 0).
The mean absolute error of the smooth image against it falls as segments^-2 (interpolated normals and
the facets' distance to the sphere are both O(h^2); the terminator band where the facet faces away is
O(h) wide with errors O(h)), the flat image's as segments^-1, and the smooth one is below the flat one
at every `segments`.
"""
import math
from pathlib import Path

import numpy as np
import pytest

from raytrace.camera import generate_rays
from raytrace.errors import UserError
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import load_scene, scene_from_text
from raytrace.scene.meshes import box_triangles, crease_normals, flat_normals, scene_triangles, sphere_triangles

from .conftest import to_toml

RHO, INTENSITY = 0.8, 10.0
LIGHT = np.array([3.0, 2.0, 2.0])
CAMERA = {"position": [0.0, 0.0, 4.0], "look_at": [0.0, 0.0, 0.0], "fov": 36.0, "width": 64, "height": 64}
SEGMENTS = [16, 32, 64, 128]
# a flat-shading pin: this scene rendered by `quadrature` before smooth shading existed (main at
# ad6b559), float64; smooth = false must reproduce it bit for bit
FLAT_SCENE = {
    "camera": {"position": [0.5, 1.5, 5.0], "look_at": [0.0, 0.3, 0.0], "fov": 50.0, "width": 24, "height": 20},
    "shape": [{"primitive": "sphere", "center": [-0.8, 0.6, 0.0], "radius": 0.6, "segments": 12},
              {"primitive": "cylinder", "base": [0.9, 0.0, 0.0], "top": [0.9, 1.2, 0.3], "radius": 0.4, "segments": 10,
               "reflectance": [0.7, 0.5, 0.3]},
              {"primitive": "box", "min": [-0.3, -0.4, -1.0], "max": [0.4, 0.1, 0.5]},
              {"primitive": "quad", "corners": [[-3.0, -0.4, -3.0], [-3.0, -0.4, 3.0], [3.0, -0.4, 3.0],
                                                [3.0, -0.4, -3.0]]}],
    "light": [{"type": "point", "position": [2.0, 3.0, 2.0], "intensity": 8.0},
              {"type": "directional", "direction": [0.4, -1.0, -0.3], "irradiance": 0.7}],
    "medium": {"sigma_a": 0.0, "sigma_s": 0.0},  # vacuum: the surface term alone (a directional light)
}
FLAT_PIN = Path(__file__).parent / "data" / "flat_shading_pin.npy"


def image(scene: dict):
    prep = prepare(scene_from_text(to_toml(scene), "smooth"))
    return render(prep, "quadrature", {}, RenderOptions(threads=1)).image


def sphere_scene(segments, smooth=True):
    return {"camera": dict(CAMERA),
            "shape": [{"primitive": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "segments": segments,
                       "reflectance": RHO, "smooth": smooth}],
            "light": [{"type": "point", "position": LIGHT.tolist(), "intensity": INTENSITY}],
            "medium": {"sigma_a": 0.0, "sigma_s": 0.0}}


def twin():
    """The exact sphere's radiance (H, W) and the pixels whose rays pass within 0.95 of its centre
    (inside every mesh of SEGMENTS: away from both silhouettes)."""
    cam = scene_from_text(to_toml(sphere_scene(16)), "twin").camera
    o, d = generate_rays(cam, slice(0, cam.height), slice(0, cam.width))
    b = np.einsum("ij,ij->i", o, d)
    c = np.einsum("ij,ij->i", o, o) - 1.0
    inside = b * b - c > 1.0 - 0.95 ** 2
    t = -b - np.sqrt(np.maximum(b * b - c, 0.0))
    x = o + t[:, None] * d  # unit sphere at the origin: the normal is x
    to_light = LIGHT - x
    dist = np.linalg.norm(to_light, axis=1)
    cos = np.maximum(np.einsum("ij,ij->i", x, to_light) / dist, 0.0)
    radiance = RHO / math.pi * INTENSITY * cos / dist ** 2
    return radiance.reshape(cam.height, cam.width), inside.reshape(cam.height, cam.width)


def test_smooth_sphere_converges_to_the_exact_sphere_at_second_order():
    exact, inside = twin()
    assert inside.mean() > 0.3 and np.any(inside & (exact == 0.0)) and np.any(inside & (exact > 0.0))  # a terminator
    errors = {}
    for smooth in (True, False):
        errors[smooth] = np.array([np.mean(np.abs(image(sphere_scene(n, smooth))[..., 0] - exact)[inside])
                                   for n in SEGMENTS])
    assert np.all(errors[True] < errors[False])
    order = -np.polyfit(np.log(SEGMENTS), np.log(errors[True]), 1)[0]
    flat_order = -np.polyfit(np.log(SEGMENTS), np.log(errors[False]), 1)[0]
    assert 1.7 < order < 2.5, (order, errors)
    assert 0.7 < flat_order < 1.3, (flat_order, errors)


def test_flat_shading_reproduces_the_image_before_smooth_shading():
    flat = {**FLAT_SCENE, "shape": [{**s, "smooth": False} for s in FLAT_SCENE["shape"]]}
    assert np.array_equal(image(flat), np.load(FLAT_PIN))
    assert not np.array_equal(image(FLAT_SCENE), np.load(FLAT_PIN))  # the default is smooth


def test_a_box_is_flat_with_smooth_on():
    box = {**FLAT_SCENE, "shape": FLAT_SCENE["shape"][2:]}  # the box on the quad
    assert np.array_equal(image(box), image({**box, "shape": [{**s, "smooth": False} for s in box["shape"]]}))
    tris, _, corners = scene_triangles(scene_from_text(to_toml(box), "box"), normals=True)
    assert corners is None


def test_no_nan_at_grazing_and_terminator_pixels():
    """A coarse sphere seen edge-on to the light (the terminator through the middle of the image) and
    a directional light grazing it: finite everywhere, black where the geometric side faces away."""
    scene = sphere_scene(6)
    scene["light"] = [{"type": "point", "position": [4.0, 0.0, 0.0], "intensity": 5.0},
                      {"type": "directional", "direction": [0.0, -1.0, 0.0], "irradiance": 1.0}]
    scene["shape"].append({"primitive": "cylinder", "base": [1.2, -1.0, 0.0], "top": [1.2, 1.0, 0.0], "radius": 0.2,
                           "segments": 5})
    img = image(scene)
    assert np.all(np.isfinite(img)) and img.max() > 0.0


def test_corner_normals():
    """Spheres: (corner - centre) / radius after the transform (normals by its inverse transpose);
    cylinder sides radial, caps flat; every corner normal on the side of its triangle's winding."""
    sc = {"camera": dict(CAMERA),
          "shape": [{"primitive": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "segments": 8,
                     "transform": {"scale": [2.0, 1.0, 1.0], "rotate": [0.0, 0.0, 30.0]}},
                    {"primitive": "cylinder", "base": [0.0, 0.0, 0.0], "top": [0.0, 2.0, 0.0], "radius": 0.5,
                     "segments": 6}],
          "light": [{"position": [0.0, 5.0, 0.0], "intensity": 1.0}]}
    tris, _, ids, corners = scene_triangles(scene_from_text(to_toml(sc), "n"), shape_ids=True, normals=True)
    winding = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    assert np.all(np.einsum("ijk,ik->ij", corners, winding) > 0.0)
    assert np.allclose(np.linalg.norm(corners, axis=-1), 1.0)
    rot = np.array([[math.cos(math.pi / 6), -math.sin(math.pi / 6), 0.0],
                    [math.sin(math.pi / 6), math.cos(math.pi / 6), 0.0], [0.0, 0.0, 1.0]])
    local = tris[ids == 0] @ rot / np.array([2.0, 1.0, 1.0])  # back on the unit sphere
    expect = (local / np.array([2.0, 1.0, 1.0])) @ rot.T  # the ellipsoid's gradient, rotated
    expect /= np.linalg.norm(expect, axis=-1, keepdims=True)
    assert np.allclose(corners[ids == 0], expect)  # outward: the sphere's winding
    cyl, cn = tris[ids == 1], corners[ids == 1]
    side = np.abs(cn[..., 1]).max(axis=1) < 1e-12  # the radial normals have no axial part
    assert np.count_nonzero(side) == 12
    assert np.allclose(cn[side], cyl[side] * np.array([1.0, 0.0, 1.0]) / 0.5)
    assert np.allclose(np.abs(cn[~side][..., 1]), 1.0)  # caps: the axis


def test_mesh_normals_from_the_file_else_creased(tmp_path):
    """An OBJ with `vn` keeps them; without, a sphere's soup smooths to near its radial normals while
    a cube's 90-degree edges stay sharp (CREASE_DEGREES)."""
    tris = sphere_triangles(np.zeros(3), 1.0, 24)
    tris = tris[np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1) > 0]
    pts = tris.reshape(-1, 3)
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in pts]
    (tmp_path / "plain.obj").write_text("\n".join(lines + [f"f {3 * i + 1} {3 * i + 2} {3 * i + 3}"
                                                           for i in range(len(tris))]) + "\n")
    tilted = pts + 0.3 * np.array([0.0, 0.0, 1.0])  # deliberately not radial: must be the file's
    tilted /= np.linalg.norm(tilted, axis=1, keepdims=True)
    lines_n = lines + [f"vn {x:.17g} {y:.17g} {z:.17g}" for x, y, z in tilted]
    (tmp_path / "normals.obj").write_text("\n".join(lines_n + [f"f {3 * i + 1}//{3 * i + 1} {3 * i + 2}//{3 * i + 2} "
                                                               f"{3 * i + 3}//{3 * i + 3}" for i in range(len(tris))])
                                          + "\n")

    def corners_of(name):
        sc = {"camera": dict(CAMERA), "shape": [{"mesh": name}],
              "light": [{"position": [0.0, 5.0, 0.0], "intensity": 1.0}]}
        path = tmp_path / f"{name}.toml"
        path.write_text(to_toml(sc))
        return scene_triangles(load_scene(path), normals=True)[2]

    assert np.allclose(corners_of("normals.obj").reshape(-1, 3), tilted, atol=1e-6)
    creased = corners_of("plain.obj").reshape(-1, 3)
    assert np.min(np.einsum("ij,ij->i", creased, pts)) > math.cos(math.radians(5.0))
    facets = np.repeat(flat_normals(tris), 3, axis=0)
    assert np.max(np.linalg.norm(creased - pts, axis=1)) < 0.5 * np.max(np.linalg.norm(facets - pts, axis=1))
    cube = box_triangles(np.zeros(3), np.ones(3))
    assert np.allclose(crease_normals(cube) / np.linalg.norm(crease_normals(cube), axis=-1, keepdims=True),
                       flat_normals(cube)[:, None, :])


def test_smooth_must_be_a_boolean():
    sc = sphere_scene(8)
    sc["shape"][0]["smooth"] = "yes"
    with pytest.raises(UserError, match=r"shape\[0\]\.smooth: expected true or false"):
        scene_from_text(to_toml(sc), "smooth")


def test_triangles_normals_and_pbrt_n(tmp_path):
    """`triangles` take a normal per vertex (pbrt's "N", read by the pbrt importer through the
    object's transform by its inverse transpose); a wrong count is refused in one line."""
    from raytrace.io import pbrt

    verts = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    normals = [[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, 0.6, 0.8]]
    sc = sphere_scene(8)
    sc["shape"] = [{"primitive": "triangles", "vertices": verts, "faces": [[0, 1, 2]], "normals": normals}]
    corners = scene_triangles(scene_from_text(to_toml(sc), "t"), normals=True)[2]
    assert np.allclose(corners[0], normals)
    sc["shape"][0]["normals"] = normals[:2]
    with pytest.raises(UserError, match=r"shape\[0\]\.normals: needs one normal per vertex \(3\), got 2"):
        scene_from_text(to_toml(sc), "t")
    (tmp_path / "n.pbrt").write_text(
        'LookAt 0 0 5  0 0 0  0 1 0\nCamera "perspective"\nWorldBegin\nLightSource "point" "point3 from" [0 0 5]\n'
        'Scale 2 1 1\nShape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 2] '
        '"normal N" [0 0 1 0.6 0 0.8 0 0.6 0.8]\n')
    shape = pbrt.read_scene(tmp_path / "n.pbrt")["shape"][0]
    expect = np.array(normals) / np.array([2.0, 1.0, 1.0])  # the inverse transpose of diag(2, 1, 1)
    expect[:, 0] *= -1.0  # a plain LookAt: read with world x negated (pbrt.py), the vertices and their normals
    assert np.allclose(shape["normals"], expect)
