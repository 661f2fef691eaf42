"""Media inside finely tessellated shapes (crossing.py, paths.py, scene/meshes.py convex_planes).

The convexity test (Qhull facets matched by a k-d tree) against known shapes and in memory linear in
the triangle count; Embree's batched exits from inside a convex mesh against a brute-force minimum
over its face planes (numpy, no Embree); a fine sphere rendered through the Embree exits against the
same sphere through media/slab.py's plane kernel; and (slow) a 512-segment sphere primitive against
a twin on the exact sphere (scipy quad, analytic chords), its error falling as the tessellation's
O(1 / segments^2); (peers) Blender's own icospheres the same way.
"""
import math
import shutil
import subprocess
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate

from raytrace.interiors import paths, shapes
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text
from raytrace.scene.meshes import box_triangles, convex_planes, sphere_triangles

from . import oracle
from .conftest import to_toml
from .test_inside_paths import u_obj


def normals_of(tris):
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    return n / np.linalg.norm(n, axis=1)[:, None]


def real(tris):
    """Without the zero-area triangles at a sphere's poles (the scene drops them too)."""
    return tris[np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1) > 0.0]


def test_convexity_of_known_shapes():
    box = box_triangles(np.array([-1.0, 0.0, 2.0]), np.array([3.0, 0.5, 4.0]))
    planes = convex_planes(box, normals_of(box))
    want = {(-1, 0, 0, 1.0), (1, 0, 0, 3.0), (0, -1, 0, 0.0), (0, 1, 0, 0.5), (0, 0, -1, -2.0), (0, 0, 1, 4.0)}
    assert {tuple(np.round(p, 12) + 0.0) for p in planes} == want
    sphere = real(sphere_triangles(np.zeros(3), 1.0, 48))
    assert len(convex_planes(sphere, normals_of(sphere))) == 48 * 22 + 2 * 48  # 22 rows of planar quads, 2 caps of triangles
    dented = sphere.copy()
    dented[np.all(np.isclose(dented, sphere[300, 0]), axis=2)] *= 1.0 - 1e-7  # one vertex 1e-7 inward
    assert convex_planes(dented, normals_of(dented)) is None
    rows = [line.split()[1:] for line in u_obj().splitlines()]
    v = np.array([r for r, line in zip(rows, u_obj().splitlines()) if line[0] == "v"], float)
    u = v[np.array([r for r, line in zip(rows, u_obj().splitlines()) if line[0] == "f"], int) - 1]
    assert convex_planes(u, normals_of(u)) is None
    flat = box_triangles(np.zeros(3), np.array([1.0, 0.0, 1.0]))[[4, 5, 6, 7]]  # the two faces of a unit square
    assert convex_planes(flat, normals_of(flat)) is None


def test_convexity_memory_is_linear():
    """A 256-segment sphere (65k triangles; every vertex against every plane would take 48 GiB, and
    783 GiB at 512 segments, which the slow test below renders): one plane per planar quad and per
    cap triangle, exactly (179 quads' two triangles used to round to planes 1e-12 apart, kept as two,
    and light through them was counted twice)."""
    tris = real(sphere_triangles(np.array([0.3, -0.2, 0.1]), 2.0, 256))
    n = normals_of(tris)
    tracemalloc.start()
    planes = convex_planes(tris, n)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert planes is not None and len(planes) == 256 * 126 + 2 * 256
    assert peak < 12 * tris.nbytes, peak / tris.nbytes


SPHERE = {"camera": {"position": [0.0, 0.5, 3.0], "look_at": [0.0, 0.0, 0.0], "fov": 40.0, "width": 12,
                     "height": 8, "spp": 1},
          "medium": {"sigma_a": 0.02},
          "shape": [{"primitive": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "segments": 24,
                     "interior": {"sigma_a": [0.3, 0.2, 0.1], "sigma_s": [0.5, 0.4, 0.3],
                                  "phase": {"type": "hg", "g": 0.4}}}],
          "light": [{"type": "point", "position": [2.0, 2.0, 1.0], "intensity": 5.0}]}


def sphere_prep(segments):
    sc = {**SPHERE, "shape": [SPHERE["shape"][0] | {"segments": segments}]}
    return sc, prepare(scene_from_text(to_toml(sc), "sphere"))


def test_batched_exits_match_the_face_planes():
    """From random points inside a 100-segment sphere toward random directions, and toward a point
    light at random distances: the exit against min over the planes the ray leaves through."""
    _, prep = sphere_prep(100)
    tris = prep.accel.triangles
    n = normals_of(tris)
    n *= np.sign(np.einsum("ij,ij->i", n, tris.mean(axis=1)))[:, None]  # outward (centred at the origin)
    c = np.einsum("ij,ij->i", n, tris[:, 0])
    rng = np.random.default_rng(5)
    p = rng.normal(size=(400, 3))
    p *= (0.97 * rng.random(400) ** (1 / 3) / np.linalg.norm(p, axis=1))[:, None]
    d = rng.normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    dist = np.where(np.arange(400) % 2, np.inf, 2.0 * rng.random(400))
    den = d @ n.T
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(den > 0.0, (c[None, :] - p @ n.T) / den, np.inf)
    want = np.minimum(t.min(axis=1), dist)
    got = paths.convex_exits(prep, 0, p, d, dist)
    assert np.max(np.abs(got - want)) < 1e-12


def test_a_fine_sphere_through_embree_exits_matches_the_plane_kernel(monkeypatch):
    """24 segments: 300 face planes, beyond shapes.KERNEL_PLANES (quadrature's exits from the facet
    walk, started from Embree's facet); the same shape through media/slab.py's convex kernel (every
    plane at every evaluation) to the quadrature's 1e-9."""
    sc, prep = sphere_prep(24)
    assert not len(shapes.convex_planes(prep, 0)) and shapes.hull_planes(prep, 0) is not None
    img = render(prep, "quadrature", {}, RenderOptions(threads=1)).image
    monkeypatch.setattr(shapes, "KERNEL_PLANES", 10**6)
    _, prep = sphere_prep(24)
    assert len(shapes.convex_planes(prep, 0)) == len(shapes.hull_planes(prep, 0))
    ref = render(prep, "quadrature", {}, RenderOptions(threads=1)).image
    lit = ref > 0
    assert lit.sum() > 100 and np.all(img[~lit] == 0)
    assert np.max(np.abs(img - ref)[lit] / ref[lit]) < 1e-9


def sphere_chord(o, d, r=1.0):
    """(t0, t1) of the line o + t d in the sphere |x| <= r, or None."""
    b = float(o @ d)
    q = b * b - (float(o @ o) - r * r)
    if q <= 0.0:
        return None
    return -b - math.sqrt(q), -b + math.sqrt(q)


def exact_pixel(sc, i, j):
    """The single scattering of the exact unit sphere along the pixel's centre ray (scipy quad) from
    its one light: a point or spot light (the spot's falloff toward each point, the ray cut at its cone
    crossings, oracle.cone_crossings) or a directional one (its irradiance, k along its direction)."""
    o, d = oracle.camera_ray(sc["camera"], i, j)
    t0, t1 = sphere_chord(o, d)
    inner = sc["shape"][0]["interior"]
    ks = np.array(inner["sigma_s"])
    kt = np.array(inner["sigma_a"]) + ks
    kt_out = sc["medium"]["sigma_a"]
    light = sc["light"][0]
    sun = light.get("type") == "directional"
    breaks = [] if sun else oracle.cone_crossings(o, d, t1, np.array(light["position"], float), oracle.spot_of(light))
    edges = [t0] + sorted(x for x in breaks if t0 < x < t1) + [t1]
    out = np.zeros(3)
    for c in range(3):
        def f(t):
            X = o + t * d
            if sun:
                u = -np.array(light["direction"], float) / np.linalg.norm(light["direction"])
                k = sphere_chord(X, u)[1]
                tau, e = kt_out * t0 + kt[c] * (t - t0 + k), light["irradiance"]
            else:
                u, dist, e, _ = oracle.lamp_at(light, X)
                k = sphere_chord(X, u)[1]
                tau = kt_out * t0 + kt[c] * (t - t0 + k) + kt_out * (dist - k)
            return ks[c] * oracle.phase("hg", inner["phase"]["g"], float(u @ d)) * math.exp(-tau) * e
        out[c] = sum(integrate.quad(f, a, b, epsabs=0.0, epsrel=1e-11, limit=200)[0] for a, b in zip(edges, edges[1:]))
    return out


@pytest.mark.slow
def test_a_512_segment_sphere_converges_to_the_exact_sphere():
    """Pixels whose centre ray crosses the sphere well inside (chord > 0.8): the tessellated sphere's
    error against the exact one falls ~16x from 128 to 512 segments (O(1 / segments^2))."""
    errs = []
    for segments in (128, 512):
        sc, prep = sphere_prep(segments)
        errs.append(error_against_the_exact_sphere(sc, render(prep, "quadrature", {}, RenderOptions(threads=1)).image))
    print("relative error against the exact sphere at 128 and 512 segments:", errs)
    assert 8.0 < errs[0] / errs[1] < 32.0 and errs[1] < 1e-3, errs


def blender_icospheres(folder, levels):
    maker = Path(__file__).parent / "data" / "blender" / "make_icospheres.py"
    subprocess.run(["blender", "-b", "--factory-startup", "--python", str(maker), "--", str(folder), *map(str, levels)],
                   check=True, capture_output=True, timeout=600)
    return [folder / f"icosphere_{level}.ply" for level in levels]


def error_against_the_exact_sphere(sc, img):
    """The largest relative error of the pixels whose centre ray crosses the sphere well inside."""
    err = 0.0
    for j in range(sc["camera"]["height"]):
        for i in range(sc["camera"]["width"]):
            chord = sphere_chord(*oracle.camera_ray(sc["camera"], i, j))
            if chord is not None and chord[1] - chord[0] > 0.8:
                ref = exact_pixel(sc, i, j)
                err = max(err, float(np.max(np.abs(img[j, i] - ref) / ref)))
    return err


@pytest.mark.peers
@pytest.mark.skipif(shutil.which("blender") is None, reason="needs Blender (Debian: apt-get install blender)")
def test_blender_icospheres_converge_to_the_exact_sphere(tmp_path):
    """Closed meshes made by Blender (levels 5 and 7: 5,120 and 81,920 triangles, vertices on the unit
    sphere) read as PLY: found convex with one plane per face in memory linear in their size, and their
    quadrature images approach the exact sphere as the faces' sagitta, 4x per level (measured 2.1e-3
    and 1.3e-4; level 4's 1,280 triangles 8.4e-3)."""
    errs = []
    for path in blender_icospheres(tmp_path, (5, 7)):
        sc = {**SPHERE, "shape": [{"mesh": str(path), "interior": SPHERE["shape"][0]["interior"]}]}
        prep = prepare(scene_from_text(to_toml(sc), "icosphere"))
        tris = prep.accel.triangles
        tracemalloc.start()
        planes = convex_planes(tris, normals_of(tris))
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert planes is not None and len(planes) == len(tris) and peak < 12 * tris.nbytes
        errs.append(error_against_the_exact_sphere(sc, render(prep, "quadrature", {}, RenderOptions(threads=1)).image))
    assert 8.0 < errs[0] / errs[1] < 32.0 and errs[1] < 3e-4, errs
