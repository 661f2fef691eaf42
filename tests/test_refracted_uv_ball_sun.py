"""The sun into glass UV spheres of 512 face planes (32 segments) and 32768 (256 segments): more planes
than the index-matched kernel's KERNEL_PLANES, each quad's two triangles in one plane (scene/meshes.py
`convex_planes` joins them), so that the planes are a little off the triangles (measured, interiors/rows.py
`measured_plane_errors`) and a beam's neighbours are nearly parallel to it (at 256 segments, 0.025 rad).

The twin is tests/test_refracted_mesh_sun.py's, from the triangles alone, vectorised over them: for each
triangle the sun meets, Snell's and Fresnel's laws by angles give the beam's direction t and irradiance
E T cos_i / cos_t; the point p(x) + s u (u = -t) where the path back meets the triangle's plane is affine
in x, so its barycentric coordinates are, and the triangle is lit on one interval of x, from their
values at the segment's ends; scipy quad integrates ks Phi E exp(-sigma_t (x + s)) over it. The two
triangles of a quad make two beams (they split the quad's), as the renderer's one plane does.

Slow (the 32x24 and 256-segment renders and their twins, ~2 min): `python -m pytest -m slow
tests/test_refracted_uv_ball_sun.py`.
"""
import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.interiors import shapes
from raytrace.scene.meshes import sphere_triangles

from . import oracle
from .test_bounded_media import fresnel_t, snell
from .test_refracted_mesh_faces import image
from .test_refracted_mesh_sun import SUN, twin

CAMERA = {"position": [0.0, 0.5, 3.0], "look_at": [0.0, 0.0, 0.0], "fov": 40.0, "width": 8, "height": 6, "spp": 1}


def uv_ball(segments, width, height):
    return {"name": f"glass_uv{segments}", "camera": {**CAMERA, "width": width, "height": height},
            "medium": {"sigma_a": 0.0},
            "shape": [{"primitive": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "segments": segments,
                       "interior": {"sigma_a": [0.3, 0.2, 0.1], "sigma_s": [0.5, 0.4, 0.3],
                                    "phase": {"type": "hg", "g": 0.4}, "ior": 1.5}}],
            "light": [SUN]}


def uv_triangles(scene):
    """(T, 3, 3) vertices of the sphere's triangles of nonzero area, their outward unit normals and
    offsets, and each one's beam of the sun: (lit, u (T, 3), E (T,)), u = -t, lit where it faces the sun."""
    shape = scene["shape"][0]
    tri = np.asarray(sphere_triangles(np.array(shape["center"], float), shape["radius"], shape["segments"]), float)
    tri = tri.reshape(-1, 3, 3)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(n, axis=1)
    tri, n = tri[area > 0.0], n[area > 0.0] / area[area > 0.0, None]
    n *= np.sign(np.einsum("ij,ij->i", n, tri.mean(axis=1)))[:, None]
    s = np.array(SUN["direction"], float)
    s /= np.linalg.norm(s)
    eta = shape["interior"]["ior"]
    lit = n @ s < 0.0
    u, e = np.zeros((len(tri), 3)), np.zeros(len(tri))
    for k in np.nonzero(lit)[0]:
        t, ti, tt = snell(s, n[k], eta)
        u[k], e[k] = -t, SUN["irradiance"] * fresnel_t(ti, tt, eta) * math.cos(ti) / math.cos(tt)
    return tri, n, np.einsum("ij,ij->i", n, tri[:, 0]), (lit, u, e)


def affine_barycentric(P0, P1, tri):
    """Barycentric coordinates (K, 3) of P0 and P1 (K, 3) in the triangles tri (K, 3, 3)."""
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    d11, d12, d22 = (np.einsum("ij,ij->i", a, b) for a, b in ((e1, e1), (e1, e2), (e2, e2)))
    det = d11 * d22 - d12 * d12
    out = []
    for P in (P0, P1):
        q = P - tri[:, 0]
        b1, b2 = np.einsum("ij,ij->i", q, e1), np.einsum("ij,ij->i", q, e2)
        uu, vv = (d22 * b1 - d12 * b2) / det, (d11 * b2 - d12 * b1) / det
        out.append(np.stack([1.0 - uu - vv, uu, vv], axis=1))
    return out


def uv_segment(scene, geometry, p, w, ell):
    """The sun's single scattering (3,) over the inside segment p + x w, x in [0, ell] (module docstring)."""
    tri, normals, offsets, (lit, u, e) = geometry
    inner = scene["shape"][0]["interior"]
    ks = np.array(inner["sigma_s"], float)
    kt = np.array(inner["sigma_a"], float) + ks
    k = np.nonzero(lit)[0]
    n, c, uk = normals[k], offsets[k], u[k]
    q = np.einsum("ij,ij->i", n, uk)
    s0, s1 = (c - n @ p) / q, (c - n @ (p + ell * w)) / q
    b0, b1 = affine_barycentric(p + s0[:, None] * uk, p + ell * w + s1[:, None] * uk, tri[k])
    lo, hi = np.zeros(len(k)), np.full(len(k), ell)
    with np.errstate(divide="ignore", invalid="ignore"):
        root = -b0 * ell / (b1 - b0)
    for j in range(3):  # b0 + (b1 - b0) x / ell >= 0
        up, down, flat = b1[:, j] > b0[:, j], b1[:, j] < b0[:, j], b1[:, j] == b0[:, j]
        lo = np.where(up, np.maximum(lo, root[:, j]), lo)
        hi = np.where(down, np.minimum(hi, root[:, j]), hi)
        hi = np.where(flat & (b0[:, j] < 0.0), -1.0, hi)
    out = np.zeros(3)
    for i in np.nonzero(hi > lo)[0]:
        mid = p + 0.5 * (lo[i] + hi[i]) * w
        den = normals @ uk[i]
        exit_ = np.min(np.where(den > 0.0, (offsets - normals @ mid) / np.where(den > 0.0, den, 1.0), np.inf))
        depth_mid = (c[i] - n[i] @ mid) / q[i]
        assert abs(exit_ - depth_mid) <= 1e-9 * (1.0 + depth_mid), (exit_, depth_mid)  # leaves through it
        ph = oracle.phase("hg", inner["phase"]["g"], float(uk[i] @ w))
        depth = lambda x: (c[i] - n[i] @ (p + x * w)) / q[i]  # noqa: E731
        out += e[k[i]] * ks * ph * integrate.quad_vec(lambda x: np.exp(-kt * (x + depth(x))), lo[i], hi[i],
                                                       epsabs=0.0, epsrel=1e-12)[0]
    return out


def check(scene, ref, method, params, median):
    """The render against the twin `ref`: every lit pixel's bound finite and above the error, and the
    unlit ones 0; the bound's median over the value at most `median`. Returns the image, the largest
    relative error and the median bound / value."""
    res = image(scene, method, params)
    err = np.abs(res.image - ref)
    lit = ref > 0.0
    assert np.all(np.isfinite(res.error_bound))
    assert np.all(err <= res.error_bound), np.max(err / res.error_bound)
    assert np.all(res.image[~lit] == 0.0)
    ratio = float(np.median(res.error_bound[lit] / ref[lit]))
    assert ratio <= median, ratio
    return res, float(np.max(err[lit] / ref[lit])), ratio


def test_the_sun_into_a_512_plane_uv_ball():
    """8x6: quadrature (rtol 1e-6) and analytic against the twin on every pixel; their bounds finite,
    above the error, median at most 10 rtol of the value (quadrature) and 1e-6 (analytic)."""
    scene = uv_ball(32, 8, 6)
    geometry = uv_triangles(scene)
    ref = twin(scene, geometry[:3], lambda sc, g, p, w, ell: uv_segment(sc, geometry, p, w, ell))
    assert np.count_nonzero(ref[..., 1] > 0.0) >= 20
    _, err, _ = check(scene, ref, "quadrature", {"rtol": 1e-6}, 1e-5)
    assert err < 1e-6
    _, err, _ = check(scene, ref, "analytic", {}, 1e-6)
    assert err < 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("segments, width, height", [(32, 32, 24), (256, 4, 3)], ids=["512planes32x24", "256seg4x3"])
def test_the_sun_into_fine_uv_balls(segments, width, height):
    """The 512-plane ball at 32x24 and the 256-segment ball (32768 planes) at 4x3: analytic and quadrature
    against the twin, every bound finite and above the error, median at most 1e-5 of the value (10 rtol
    for quadrature, rtol 1e-6). Before, the 256-segment ball's median was 8.8e-5: each beam's bound
    counted the spans of its interval's ends also where its whole interval, true or computed, was empty
    (now the spans are cut to where either interval may lie)."""
    scene = uv_ball(segments, width, height)
    geometry = uv_triangles(scene)
    assert len(geometry[0]) > shapes.KERNEL_PLANES
    ref = twin(scene, geometry[:3], lambda sc, g, p, w, ell: uv_segment(sc, geometry, p, w, ell))
    for method, params in (("analytic", {}), ("quadrature", {"rtol": 1e-6})):
        _, err, ratio = check(scene, ref, method, params, 1e-5)
        print(method, segments, "largest relative error", err, "median bound / value", ratio)
