"""media/convex_chords.py: the chords of segments through convex shapes against trimesh's float64
ray-triangle crossings (a parity twin that knows nothing of face planes: brute-force Moller-Trumbore
on trimesh's meshes), and its kernel of
paths.through_quadrature against the NumPy driver it replaces (paths.adaptive with
paths.through_integrand) on the pieces of a render: the same rule, so the same numbers to
rounding."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from raytrace.interiors import paths, shapes
from raytrace.media.convex_chords import PLANES, boundary_chords, section_kinks
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import render

from .test_interior_shadows import FOG_KA, FOG_KS, OUT_CAMERA, OUT_KA, OUT_KS, write


def rotated(mesh, seed):
    """`mesh` turned by a random rotation and moved off the origin."""
    rng = np.random.default_rng(seed)
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    m = np.eye(4)
    m[:3, :3] = q * np.sign(np.diag(r))
    m[:3, 3] = rng.uniform(-0.5, 0.5, 3)
    return mesh.copy().apply_transform(m)


SHAPES = {
    "box": rotated(trimesh.creation.box(extents=[1.0, 0.6, 1.4]), 1),
    "triangular prism": rotated(trimesh.creation.cylinder(radius=0.7, height=1.1, sections=3), 2),
    "pentagonal prism": rotated(trimesh.creation.cylinder(radius=0.5, height=0.4, sections=5), 3),
}


def crossings(tris, p, u):
    """(N, T) distances along the rays p + s u (s > 0) to their crossings of each triangle, inf where
    they miss it: Moller-Trumbore in float64, brute force."""
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    pv = np.cross(u[:, None, :], e2[None])
    det = np.einsum("tj,ntj->nt", e1, pv)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        tv = p[:, None, :] - tris[None, :, 0]
        a = np.einsum("ntj,ntj->nt", tv, pv) * inv
        qv = np.cross(tv, e1[None])
        b = np.einsum("nj,ntj->nt", u, qv) * inv
        s = np.einsum("tj,ntj->nt", e2, qv) * inv
    hit = (det != 0.0) & (a >= 0.0) & (b >= 0.0) & (a + b <= 1.0) & (s > 0.0)
    return np.where(hit, s, np.inf)


def parity_chord(mesh, p, u, dist):
    """Length of p + s u, 0 <= s <= dist, inside the closed mesh, from the crossings of the ray from
    p with its triangles, sorted: the inside runs lie between them, starting at p if their count is
    odd. Also whether p is inside."""
    hits = crossings(mesh.triangles, p, u)
    out = np.zeros(len(p))
    inside = np.zeros(len(p), dtype=bool)
    for i in range(len(p)):
        s = np.sort(hits[i][np.isfinite(hits[i])])
        s = s[np.concatenate([[True], np.diff(s) > 1e-9])] if len(s) else s  # an edge: in both triangles
        inside[i] = len(s) % 2 == 1
        edges = np.concatenate([[0.0], s]) if inside[i] else s
        for a, b in zip(edges[::2], edges[1::2]):
            out[i] += max(min(b, dist[i]) - min(a, dist[i]), 0.0)
    return out, inside


@pytest.mark.parametrize("name", SHAPES)
def test_chords_equal_trimesh_ray_tests(name):
    """boundary_chords on every triangle's plane (float64 from the vertices) against the parity
    twin to 1e-12 on 400 random segments from points around the shape and a quarter inside it, half
    aimed at it, finite and infinite."""
    mesh = SHAPES[name]
    rng = np.random.default_rng(7)
    n = 400
    p = mesh.bounds.mean(axis=0) + rng.uniform(-1.5, 1.5, (n, 3)) * mesh.extents
    p[::4] = 0.5 * (mesh.sample(n // 4, seed=9) + mesh.centroid)  # strictly inside (convex)
    aim = mesh.sample(n, seed=8) * 0.9 + 0.1 * mesh.centroid - p
    u = np.where((np.arange(n) % 2 == 0)[:, None], aim, rng.normal(size=(n, 3)))
    u /= np.linalg.norm(u, axis=1)[:, None]
    dist = np.where(np.arange(n) % 3 == 0, np.inf, rng.uniform(0.0, 4.0, n))
    normals = mesh.face_normals
    planes = np.column_stack([normals, np.einsum("ij,ij->i", normals, mesh.triangles[:, 0])])
    got = np.empty(n)
    boundary_chords(p, u, dist, PLANES, planes, got)
    ref, inside = parity_chord(mesh, p, u, dist)
    assert np.count_nonzero(ref > 0.0) >= 100 and inside[::4].all()
    print(f"{name}: worst |chord - twin| {np.max(np.abs(got - ref)):.1e}")
    assert np.max(np.abs(got - ref)) <= 1e-12


def test_a_segment_along_a_face_outside_it_has_no_chord():
    """A segment parallel to a face and beyond it: 0 (the clip's empty case), not a NaN."""
    planes = np.array([[1.0, 0.0, 0.0, 1.0], [-1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0], [0.0, -1.0, 0.0, 1.0],
                       [0.0, 0.0, 1.0, 1.0], [0.0, 0.0, -1.0, 1.0]])
    out = np.empty(2)
    boundary_chords(np.array([[2.0, 0.0, -3.0], [0.5, 0.0, -3.0]]), np.array([[0.0, 0.0, 1.0]] * 2),
                    np.array([np.inf, 10.0]), PLANES, planes, out)
    assert out.tolist() == [0.0, 2.0]


def scene(tmp_path):
    """The fog of test_interior_shadows lit by a point light and a spot (its cone edge across the
    view), with two index-matched boxes in the light's paths."""
    return write(tmp_path, {
        "name": "fog under two boxes", "camera": OUT_CAMERA | {"width": 12, "height": 9},
        "medium": {"type": "homogeneous", "sigma_a": FOG_KA.tolist(), "sigma_s": FOG_KS.tolist()},
        "light": [{"type": "point", "position": [0.0, 3.0, 0.0], "intensity": 10.0},
                  {"type": "spot", "position": [1.5, 3.0, 0.5], "intensity": 8.0, "direction": [-0.3, -1.0, 0.1],
                   "cone_angle": 30.0, "falloff_start": 20.0}],
        "shape": [{"primitive": "box", "min": [-0.4, 1.2, -0.6], "max": [0.6, 2.0, 0.4],
                   "interior": {"sigma_a": OUT_KA.tolist(), "sigma_s": OUT_KS.tolist()}},
                  {"primitive": "box", "min": [0.7, 1.5, -0.2], "max": [1.2, 1.9, 0.9],
                   "interior": {"sigma_a": [0.1, 0.1, 0.1], "sigma_s": [0.02, 0.03, 0.04]}}]})


def first_panels(prep, segs, sids, end):
    """(piece, start, end) of the panels between the pieces' kinks (section_kinks of every shape)."""
    seg, lo, hi = [], [], []
    for i in np.nonzero(end > 0.0)[0]:
        cuts = []
        for sid in sids:
            planes = prep.interior_planes[sid]
            found = np.empty(len(planes) + 4)
            n = section_kinks(planes, 0, len(planes), segs.origins[i], segs.dirs[i],
                              prep.lights.position[segs.light[i]], end[i], found)
            cuts += found[:n].tolist()
        edges = np.unique([0.0, *cuts, end[i]])
        seg += [i] * (len(edges) - 1)
        lo += edges[:-1].tolist()
        hi += edges[1:].tolist()
    return np.array(seg), np.array(lo), np.array(hi)


def test_the_kernel_integrates_as_the_numpy_driver(tmp_path, monkeypatch):
    """On the pieces behind the boxes of a render (both lights, both boxes), through_quadrature's
    kernel equals paths.adaptive over through_integrand (chords by boundary_chords), started from
    the same first panels (cut at each shape's section_kinks), to 1e-12 relative per piece and
    channel, with the same count of unconverged panels (none). (Started from whole pieces, as both
    were before the kernel cut them, the rule missed a kink of piece 99: 5.4e-6 off at rtol 1e-10,
    against 3e-10 from the kinks, measured against 4000 equal 20-point panels.)"""
    prep = scene(tmp_path)
    seen = []
    real = paths.through_quadrature

    def spy(prep, segs, medium, sids, kt_in, rtol, stats, *errors):
        seen.append((segs, sids, kt_in, rtol))
        return real(prep, segs, medium, sids, kt_in, rtol, stats, *errors)

    monkeypatch.setattr(paths, "through_quadrature", spy)
    render(prep, "quadrature", {}, RenderOptions(threads=1, volumetric_shadows=True))
    assert seen and all(len(sids) == 2 and all(prep.interior_planes[s] is not None for s in sids)
                        for _, sids, _, _ in seen)
    medium = prep.scene.medium
    lights = set()
    for segs, sids, kt_in, rtol in seen:
        lights |= set(segs.light.tolist())
        cap_k, cap_n = np.zeros(1), np.zeros(1)
        got = real(prep, segs, medium, sids, kt_in, rtol, cap_k)[0]
        end = np.minimum(segs.length, 745.0 / float(np.min(medium.sigma_t)))
        seg, lo, hi = first_panels(prep, segs, sids, end)
        ref = paths.adaptive(paths.through_integrand(prep, segs, medium, sids, kt_in - medium.sigma_t),
                                    end, 3, seg, lo, hi, rtol, cap_n)
        assert np.all(ref > 0.0)
        rel = np.abs(got - ref) / ref
        print(f"{len(segs)} pieces: worst relative difference {rel.max():.1e}")
        assert rel.max() <= 1e-12
        assert cap_k[0] == cap_n[0] == 0.0
    assert lights == {0, 1}
    assert shapes.matched(prep) == list(seen[0][1])
