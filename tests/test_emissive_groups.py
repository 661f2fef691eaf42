"""Emissive shapes of more than 64 triangles (raytrace/lights/emissive.py): their triangles grouped into
rows of vector area, the pilot climbing from the coarsest grouping, against a twin built from the
geometry alone (numpy: each triangle's 7-point rule split in 4, Gauss-Legendre panels along the ray)."""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from raytrace import api
from raytrace.lights import cubature, emissive
from raytrace.scene.format import scene_from_text

from . import area_twin as twin
from .conftest import to_toml

SPHERE = trimesh.creation.icosphere(subdivisions=2, radius=0.3)  # 320 triangles
VERTICES, FACES = SPHERE.vertices + [0.0, 1.5, 0.0], SPHERE.faces
CAMERA = {"position": [0.0, 0.0, 4.0], "look_at": [0.0, 0.5, 0.0], "fov": 60.0, "width": 16, "height": 12}
FOG = {"sigma_a": 0.05, "sigma_s": 0.1}
KT, KS, L = 0.15, 0.1, 10.0
# pixels (row, column): a grid, and four whose rays pass by or end on the sphere
PIXELS = [(i, j) for i in range(0, 12, 3) for j in range(1, 16, 4)] + [(3, 7), (3, 8), (4, 8), (2, 8)]
A, B = (6 - math.sqrt(15)) / 21, (6 + math.sqrt(15)) / 21
BARY = np.array([[1 / 3] * 3, [A, A, 1 - 2 * A], [A, 1 - 2 * A, A], [1 - 2 * A, A, A], [B, B, 1 - 2 * B],
                 [B, 1 - 2 * B, B], [1 - 2 * B, B, B]])
WEIGHTS = np.array([9 / 40] + [(155 - math.sqrt(15)) / 1200] * 3 + [(155 + math.sqrt(15)) / 1200] * 3)


def twin_radiance(o, w, panels=64):
    """The camera ray's radiance: the air-light of every triangle (split in 4, Radon's 7-point rule)
    along graded Gauss-Legendre panels about the ray's closest approach, and the emission it ends on."""
    t = VERTICES[FACES]
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
    t = np.concatenate([np.stack(q, 1) for q in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    cross = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    y = np.einsum("kj,tjc->tkc", BARY, t).reshape(-1, 3)
    n = np.repeat(cross / (2 * area[:, None]), 7, axis=0)
    wy = (area[:, None] * WEIGHTS).ravel()
    e1, e2 = VERTICES[FACES[:, 1]] - VERTICES[FACES[:, 0]], VERTICES[FACES[:, 2]] - VERTICES[FACES[:, 0]]
    p = np.cross(w, e2)
    det = np.einsum("ij,ij->i", e1, p)
    s = o - VERTICES[FACES[:, 0]]
    q = np.cross(s, e1)
    u, v, th = np.einsum("ij,ij->i", s, p) / det, (q @ w) / det, np.einsum("ij,ij->i", e2, q) / det
    hits = th[(u >= 0) & (v >= 0) & (u + v <= 1) & (th > 0)]
    end = hits.min() if len(hits) else 250.0  # e^{-KT 250}: nothing left
    tc = min(max(0.0, (VERTICES.mean(0) - o) @ w), end)
    x, gw = np.polynomial.legendre.leggauss(16)
    g = np.linspace(0.0, 1.0, panels // 2 + 1) ** 3
    edges = np.unique(np.concatenate([tc * (1 - g), tc + (end - tc) * g]))
    h = np.diff(edges)
    ts, wt = (edges[:-1, None] + 0.5 * h[:, None] * (x + 1)).ravel(), (0.5 * h[:, None] * gw).ravel()
    d = (o + ts[:, None] * w)[:, None, :] - y[None]
    r = np.linalg.norm(d, axis=2)
    irradiance = L * np.sum(wy * np.maximum(np.einsum("tij,ij->ti", d, n), 0.0) * np.exp(-KT * r) / r**3, axis=1)
    air = np.sum(wt * np.exp(-KT * ts) * KS / (4 * math.pi) * irradiance)
    return air + (L * math.exp(-KT * end) if len(hits) else 0.0)


@pytest.fixture(scope="module")
def reference():
    o = np.array(CAMERA["position"], float)
    dirs = twin.camera_rays(o, CAMERA["look_at"], [0.0, 1.0, 0.0], CAMERA["fov"], 16, 12)
    return np.array([twin_radiance(o, dirs[i, j]) for i, j in PIXELS])


def scene():
    shape = {"primitive": "triangles", "vertices": VERTICES.tolist(), "faces": FACES.tolist(), "emission": L}
    return scene_from_text(to_toml({"camera": CAMERA, "shape": [shape], "light": [], "medium": FOG}), "emissive.toml")


def test_groups_keep_the_vector_area_and_nest():
    tris = VERTICES[FACES]
    cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    total = 0.5 * cross.sum(axis=0)
    counts = []
    for level in (-1, -2, -3, -4):
        points, vector = emissive.groups(tris, cross, area, level)
        np.testing.assert_allclose(vector.sum(axis=0), total, rtol=0, atol=1e-14)
        assert np.all(np.linalg.norm(points - VERTICES.mean(axis=0), axis=1) <= 0.3 + 1e-12)  # inside the hull
        counts.append(len(points))
    assert counts[0] == 320 and all(4 * b >= a > b for a, b in zip(counts, counts[1:]))
    rows = emissive.rows(tris, [L] * 3, False, "x", -1)
    np.testing.assert_allclose(np.sort(rows.intensity[:, 0]), np.sort(L * area), rtol=1e-15)  # level -1: a row each


def test_at_the_rows_cap_the_pilot_says_so_and_the_rows_hold_the_precision(reference):
    """320 triangles: the 7-point rule (2,240 rows) is beyond the pilot's 1024 rows, so it keeps one row
    a triangle (its centroid), counts the emitter capped and its rays not converged; the pixels away
    from the sphere hold the requested 1e-3 all the same (the near ones are the pilot's near rays)."""
    result = api.render(scene(), "quadrature", rtol=1e-3)
    got = np.array([result.array[i, j, 0] for i, j in PIXELS])
    assert result.stats["cubature: rows"] == 320 and result.stats["cubature: emitters capped"] == 1
    assert result.stats["cubature: pilot rays not converged"] > 0
    assert np.all(np.abs(got / reference - 1.0)[:16] < 1e-3)


@pytest.mark.parametrize("method,options", [("quadrature", {"rtol": 1e-3}), ("analytic", {"precision": 1e-3})])
def test_with_the_cap_lifted_the_pilot_climbs_to_the_7_point_rule(reference, monkeypatch, method, options):
    """The ladder from 20 groups of 16 triangles to the 7-point rule: it agrees with the twin to the
    pilot's SHARE of the precision on every pixel, the rays that end on the sphere included."""
    monkeypatch.setattr(cubature, "MAX_ROWS", 4096)
    result = api.render(scene(), method, **options)
    got = np.array([result.array[i, j, 0] for i, j in PIXELS])
    assert result.stats["cubature: rows"] == 2240
    assert np.all(np.abs(got / reference - 1.0) < cubature.SHARE * 1e-3)


def test_a_large_shape_starts_coarse_and_fixed_rules_stay_small():
    many = trimesh.creation.icosphere(subdivisions=4)  # 5,120 triangles
    tris = many.vertices[many.faces]
    first = emissive.levels(len(tris), cubature.LEVELS)[0]
    assert emissive.count(tris, False, first) <= 64 + 6 and emissive.count(tris, False, first + 1) > 64
    fixed = emissive.default_level(len(tris))
    assert emissive.count(tris, True, fixed) <= 2 * (448 + 6) and emissive.count(tris, False, fixed + 1) > 448
    assert emissive.levels(64, cubature.LEVELS)[0] == emissive.default_level(64) == 0  # small shapes as before
