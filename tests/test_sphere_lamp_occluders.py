"""Surfaces lit by a sphere light with occluders near it: the penumbra test of a sphere emitter probes
the part of the sphere each point sees (`sphere_rule.Ball.probes`, the same for every cubature order),
so the pilot keeps the coarsest rows where the surface rule gives the value (in a medium that does
not scatter), and every floor pixel still matches a twin built from the geometry alone:
- the unoccluded irradiance by the closed form of a sphere clipped by the horizon (Snyder's, mpmath);
- the part a rectangle (a plate under the lamp, a low wall beside it) hides, exactly: the cone of
  directions from the point to the sphere meets the rectangle's plane in an ellipse; over the
  rectangle's part inside it the irradiance is int (n.q)(m.q) / |q|^4 dA (q from the point to the
  plane's point, m the plane's unit normal toward it), the inner integral along one side in closed
  form and the outer by scipy between the places the ellipse crosses the rectangle's sides.
Pixels the twin finds unoccluded must match it within 1e-6 with no variance; pixels it finds partly
hidden must be sampled (a variance: the renderer saw the penumbra) and match within their noise;
fully hidden ones are black.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from raytrace import api, shading
from raytrace.lights import sphere_occluders
from raytrace.lights.sphere_rule import ARC, Ball
from raytrace.scene.format import scene_from_text

from .conftest import to_toml
from .test_sphere_lamp_surface import camera_rays, snyder

R = 0.3
LAMP = np.array([0.0, 1.0, 0.0])
RHO, L = 0.5, 10.0
FLOOR = {"primitive": "quad", "corners": [[-20.0, 0.0, 20.0], [20.0, 0.0, 20.0], [20.0, 0.0, -20.0],
                                          [-20.0, 0.0, -20.0]], "reflectance": RHO}
# (axis k of the plane's normal, its coordinate there, the other in-plane axis j and its range, the z range)
PLATE = (1, 0.45, 0, (0.19, 0.31), (0.09, 0.21))  # a small plate between the lamp and the floor
WALL = (0, 0.35, 1, (0.0, 0.9), (-0.8, 0.8))  # a low wall beside the lamp (its top below the lamp's top)
W, H = 16, 12
CAMERAS = {PLATE: {"position": [0.45, 1.2, 1.4], "look_at": [0.45, 0.0, 0.27], "fov": 50.0, "width": W, "height": H},
           WALL: {"position": [0.0, 2.0, 3.0], "look_at": [0.3, 0.0, 0.0], "fov": 50.0, "width": W, "height": H}}


def rect_shape(rect):
    k, value, j, (u0, u1), (z0, z1) = rect
    corners = []
    for u, z in ((u0, z0), (u1, z0), (u1, z1), (u0, z1)):
        p = [0.0, 0.0, z]
        p[k], p[j] = value, u
        corners.append(p)
    return {"primitive": "quad", "corners": corners, "reflectance": RHO}


def scene(rect):
    lamp = {"type": "sphere", "center": LAMP.tolist(), "radius": R, "radiance": L}
    table = {"camera": CAMERAS[rect], "shape": [FLOOR, rect_shape(rect)], "light": [lamp]}
    return scene_from_text(to_toml(table), "lamp.toml")


def inner(c2, z):
    """int_0^z dζ / (c2 + ζ^2)^2."""
    c = math.sqrt(c2)
    return z / (2.0 * c2 * (c2 + z * z)) + math.atan(z / c) / (2.0 * c2 * c)


def hidden(x, n, rect):
    """E / L the rectangle hides from the point x of unit normal n (n_z = 0), the rectangle between x and
    the whole sphere (module docstring)."""
    k, value, j, (u0, u1), (z0, z1) = rect
    rel = LAMP - x
    d = np.linalg.norm(rel)
    a = rel / d
    c2 = 1.0 - (R / d) ** 2  # cos^2 alpha
    qk = value - x[k]
    ak, aj, az = a[k], a[j], a[2]
    lead = az * az - c2  # < 0: the cone meets the plane in an ellipse

    def span(qj):
        s = ak * qk + aj * qj
        disc = (az * s) ** 2 - lead * (s * s - c2 * (qk * qk + qj * qj))
        if disc <= 0.0:
            return None
        r = math.sqrt(disc)
        lo, hi = sorted(((-az * s + r) / lead, (-az * s - r) / lead))
        lo, hi = max(lo, z0 - x[2]), min(hi, z1 - x[2])
        return (lo, hi) if hi > lo else None

    def f(u):
        qj = u - x[j]
        zs = span(qj)
        if zs is None:
            return 0.0
        q = np.zeros(3)
        q[k], q[j] = qk, qj
        cc = qk * qk + qj * qj
        return (n @ q) * abs(qk) * (inner(cc, zs[1]) - inner(cc, zs[0]))

    # the ellipse's extent in qj (where the z-discriminant vanishes) and where it crosses z = z0, z1
    breaks = list(np.roots([aj * aj + lead, 2.0 * aj * ak * qk, (ak * ak + lead) * qk * qk]).real)
    for zz in (z0 - x[2], z1 - x[2]):
        e = ak * qk + az * zz
        breaks += list(np.roots([aj * aj - c2, 2.0 * aj * e, e * e - c2 * (qk * qk + zz * zz)]).real)
    pts = sorted(b + x[j] for b in breaks if u0 < b + x[j] < u1)
    edges = [u0] + pts + [u1]
    return sum(integrate.quad(f, lo, hi, epsabs=0.0, epsrel=1e-12, limit=200)[0] for lo, hi in zip(edges, edges[1:]))


def twin(rect):
    """(H, W) radiance per pixel (NaN where the ray meets the lamp first) and (H, W) the share the
    rectangle hides from the point (0: unoccluded, 1: fully hidden)."""
    k, value, j, (u0, u1), (z0, z1) = rect
    out, share = np.full((H, W), np.nan), np.zeros((H, W))
    for row, col, o, d in camera_rays(CAMERAS[rect]):
        hits = []
        if d[1] < 0.0:
            hits.append((-o[1] / d[1], np.array([0.0, 1.0, 0.0]), True))
        t = (value - o[k]) / d[k] if d[k] != 0.0 else -1.0
        p = o + t * d
        if t > 0.0 and u0 <= p[j] <= u1 and z0 <= p[2] <= z1:
            m = np.zeros(3)
            m[k] = -math.copysign(1.0, d[k])  # toward the camera
            hits.append((t, m, False))
        oc = o - LAMP
        disc = (d @ oc) ** 2 - (oc @ oc - R * R)
        if disc >= 0.0:
            hits.append((-(d @ oc) - math.sqrt(disc), None, False))
        t, n, floor = min(hits, key=lambda h: h[0])
        if n is None:
            continue
        x = o + t * d
        rel = LAMP - x
        dist = np.linalg.norm(rel)
        full = snyder(math.acos(np.clip(n @ rel / dist, -1.0, 1.0)), dist, R)
        # the rectangle lies between the floor's points beyond it and the lamp; nothing hides the lamp
        # from the rectangle's own face or the floor on the lamp's side
        behind = floor and (x[k] - value) * (LAMP[k] - value) < 0.0
        gone = hidden(x, n, rect) if behind else 0.0
        out[row, col] = RHO / math.pi * L * (full - gone)
        share[row, col] = gone / full
    return out, share


@pytest.mark.parametrize("rect", [PLATE, WALL], ids=["plate", "wall"])
def test_occluded_floor_against_the_twin(rect):
    """Each pixel against the twin (quadrature rtol 1e-6): unoccluded within 1e-6 and no variance, partly
    hidden sampled (variance > 0) and within 5 standard errors plus 1e-6, fully hidden black; the pilot
    keeps the coarsest rule (8 rows); the scene has pixels of each kind it has."""
    ref, share = twin(rect)
    seen = ~np.isnan(ref)
    img = api.render(scene(rect), "quadrature", rtol=1e-6)
    assert img.stats["cubature: rows"] == 8
    value, var = img.array[..., 0], img.variance[..., 0]
    clear, dark = seen & (share == 0.0), seen & (share >= 1.0 - 1e-12)
    part = seen & ~clear & ~dark
    assert clear.sum() >= 20 and part.sum() >= 8, (clear.sum(), part.sum())
    assert np.all(np.abs(value[clear] / ref[clear] - 1.0) <= 1e-6), np.abs(value[clear] / ref[clear] - 1.0).max()
    assert np.all(var[clear] == 0.0)
    assert np.all(var[part] > 0.0)
    z = np.abs(value[part] - ref[part]) / (5.0 * np.sqrt(var[part]) + 1e-6 * ref[part])
    assert z.max() <= 1.0, z.max()
    assert np.all(value[dark] <= 5.0 * np.sqrt(var[dark]))


def test_the_coarse_rows_alone_miss_the_plate(monkeypatch):
    """Without the occluders' test (every point taken as free of them: the rows' verdict alone) the 8 rows
    the pilot keeps miss the plate at some floor points the twin finds partly hidden: those take the
    unoccluded rule (no variance) and are too bright."""
    ref, share = twin(PLATE)
    part = ~np.isnan(ref) & (share > 0.0) & (share < 1.0)
    monkeypatch.setattr(shading, "_free", lambda accel, points, normals, emitter: np.ones(len(points), bool))
    img = api.render(scene(PLATE), "quadrature", rtol=1e-6)
    missed = part & (img.variance[..., 0] == 0.0)
    assert missed.any()
    assert np.all(img.array[..., 0][missed] > ref[missed] * (1.0 + 1e-4))


def test_probes_lie_on_the_part_of_the_sphere_each_point_sees():
    """Every probe lies on the sphere, faces the point (in front of its tangent plane there) and within
    the cap; a horizon's probes just above it; none at points on or inside the sphere."""
    ball = Ball(np.array([0.0, 0.2, 0.0]), R)
    rng = np.random.default_rng(3)
    x = rng.normal(size=(300, 3)) * 1.5
    x[:, 1] = 0.0
    n = np.tile([0.0, 1.0, 0.0], (300, 1))
    tilted = np.tile([0.6, 0.8, 0.0], (300, 1))
    y = ball.probes(x, [n, tilted])
    outside = np.linalg.norm(x - ball.centre, axis=1) > R
    assert np.isnan(y[~outside]).all()
    y = y[outside]
    xo = x[outside][:, None, :]
    ok = ~np.isnan(y[..., 0])
    assert np.all(ok.sum(axis=1) >= 61)  # the rings' probes at least
    assert np.nanmax(np.abs(np.linalg.norm(y - ball.centre, axis=2) - R)) <= 1e-14
    facing = np.einsum("mkj,mkj->mk", y - ball.centre, xo - y)
    assert np.nanmin(facing) > 0.0
    w = (y - xo) / np.linalg.norm(y - xo, axis=2)[..., None]
    sin_a = R / np.linalg.norm(ball.centre - x[outside], axis=1)
    for i, nn in enumerate((n, tilted)):  # each horizon's crossings: 1e-3 sin alpha above it
        cols = slice(61 + 2 * ARC * i, 61 + 2 * ARC * (i + 1))
        lift = np.einsum("mkj,mj->mk", w[:, cols], nn[outside]) / sin_a[:, None]
        assert np.nanmax(np.abs(lift - 1e-3)) <= 1e-9
        assert np.isfinite(lift).sum() >= 100


def test_the_occluder_test_against_segments_to_the_sphere():
    """`sphere_occluders.free` on random floor points and random small triangles near the line to the lamp
    against brute force (numpy alone): where one of 2000 segments from the point to points of the sphere
    it sees (spread over the cap) meets the triangle above the floor, or one of 45000 points of the
    triangle lies in the test's region (the cone toward the sphere above the floor, up to the plane of
    the tangent circle: the sphere's front too), the point is not free; where neither, it is free but
    for triangles that graze the region between the samples."""
    rng = np.random.default_rng(7)
    centre = LAMP
    k = np.arange(2000) + 0.5
    cos_frac, phi = k / 2000, math.pi * (1 + 5 ** 0.5) * k  # a spiral over the cap, uniform in solid angle
    agree = total = hidden = 0
    g = np.linspace(0.0, 1.0, 300)
    bary = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    bary = bary[bary.sum(axis=1) <= 1.0]
    for _ in range(300):
        x = np.array([rng.uniform(-2, 2), 0.0, rng.uniform(-2, 2)])
        if np.linalg.norm(x - centre) <= R:
            continue
        mid = x + rng.uniform(0.1, 1.1) * (centre - x) + rng.normal(scale=0.3, size=3)  # about the line to the lamp
        tri = mid + rng.normal(scale=0.1, size=(3, 3))
        rel = centre - x
        d = np.linalg.norm(rel)
        a = rel / d
        cos_b = 1.0 - cos_frac * (1.0 - math.sqrt(1.0 - (R / d) ** 2))
        sin_b = np.sqrt(1.0 - cos_b ** 2)
        u = np.cross(a, [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(a, u)
        w = cos_b[:, None] * a + sin_b[:, None] * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v)
        s = d * cos_b - np.sqrt(np.maximum(R * R - (d * sin_b) ** 2, 0.0))
        up = w[:, 1] > 0.0
        w, s = w[up], s[up]
        e1, e2 = tri[1] - tri[0], tri[2] - tri[0]  # Moller-Trumbore
        p = np.cross(w, e2)
        det = p @ e1
        tv = x - tri[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            b1 = (p @ tv) / det
            q = np.cross(tv, e1)
            b2 = (w @ q) / det
            t = (e2 @ q) / det
        hit = (b1 >= 0) & (b2 >= 0) & (b1 + b2 <= 1) & (t > 0) & (t < s) & ((x + t[:, None] * w)[:, 1] > 1e-9)
        q = tri[0] + bary[:, :1] * e1 + bary[:, 1:] * e2 - x  # the triangle's points in the test's region
        depth = q @ a
        region = ((q[:, 1] > 1e-9) & (depth > 0.0) & (depth <= d - R * R / d) &
                  (depth >= np.linalg.norm(q, axis=1) * math.sqrt(1.0 - (R / d) ** 2)))
        free = sphere_occluders.free(centre, R, x[None], np.array([[0.0, 1.0, 0.0]]), tri[None], np.array([-1]),
                                     np.zeros((0, 4)), 1e-5)[0]
        if hit.any():
            hidden += 1
        if hit.any() or region.any():
            assert not free, (x, tri)
        else:
            total += 1
            agree += bool(free)
    assert hidden >= 60 and total >= 150 and agree >= total - 3, (hidden, agree, total)
