"""A point light's refracted paths into a convex refractive shape of more face planes than the index-matched
kernel's KERNEL_PLANES (the 512-plane glass UV ball of tests/test_refracted_edge_isolation.py under its lamp),
attenuated by another, index-matched interior on their outside legs (interiors/rows.py `_lit_point` with
`_other_interiors(..., many=True)`: shadows/through_others.py `refracted_attenuated` over the planes each
face needs): a fog box between the lamp and the ball. Before, these paths were not attenuated and the
bound was infinite on every pixel the ball holds.

The twin uses the geometry alone: tests/test_refracted_mesh_faces.py's (each triangle's Fermat path in the
plane of incidence, counted where the refraction point lies in the triangle, the ray tube's irradiance)
times exp(-(sigma_t fog - sigma_t outside) c), c the chord of the leg from the refraction point to the lamp
through the fog box by a slab test, scipy quad cut where the triangle's lit set or the faces the leg enters
and leaves the box by change (each bisected on its indicator). Slow (the twin's Fermat paths over the
ball's triangles, ~1-2 min a pixel): `python -m pytest -m slow tests/test_refracted_uv_ball_point_others.py`.
"""
import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import oracle
from .conftest import to_toml
from .test_bounded_media import fresnel_t, slab, snell
from .test_refracted_edge_isolation import LAMP_BALL
from .test_refracted_mesh_faces import exit_distance, fermat_scalar, lit_intervals
from .test_refracted_point_light import switches, tube
from .test_refracted_uv_ball_sun import uv_ball, uv_triangles

LO_F, HI_F = np.array([1.15, 1.25, 0.55]), np.array([1.4, 1.55, 0.8])  # over about half the legs
FOG = {"sigma_a": [0.9, 0.6, 0.3], "sigma_s": [0.3, 0.3, 0.3]}
SCENE = {**uv_ball(32, 16, 12), **LAMP_BALL, "name": "glass_uv32_fog"}
SCENE["shape"] = SCENE["shape"] + [{"primitive": "box", "min": LO_F.tolist(), "max": HI_F.tolist(), "interior": FOG}]
LAMP = np.array(LAMP_BALL["light"][0]["position"], float)
PIXELS = [(9, 4), (7, 6), (9, 8), (5, 3)]


def leg(R):
    """(chord, the faces it enters and leaves by) of the segment from R to the lamp in the fog box."""
    d = LAMP - R
    dist = np.linalg.norm(d)
    hit = slab(R, d / dist, LO_F, HI_F)
    if hit is None or hit[1] <= 0.0 or hit[0] >= dist:
        return 0.0, None
    leave = [max((LO_F[a] - R[a]) / d[a] * dist, (HI_F[a] - R[a]) / d[a] * dist) if d[a] else math.inf
             for a in range(3)]
    return min(hit[1], dist) - max(hit[0], 0.0), (tuple(hit[2]), int(np.argmin(leave)))


def twin_pixel(i, j, fog=True):
    """The ball's inside single scattering at pixel (i, j) (3,), its legs through the fog box (or not)."""
    tri, normals, offsets = uv_triangles(SCENE)[:3]
    inner = SCENE["shape"][0]["interior"]
    eta, g = inner["ior"], inner["phase"]["g"]
    ks = np.array(inner["sigma_s"], float)
    kt = np.array(inner["sigma_a"], float) + ks
    kt_out = SCENE["medium"]["sigma_a"]
    dk = np.array(FOG["sigma_a"], float) + np.array(FOG["sigma_s"], float) - kt_out if fog else np.zeros(3)
    inten = LAMP_BALL["light"][0]["intensity"]
    o_cam, d = oracle.camera_ray(SCENE["camera"], i, j)
    assert slab(o_cam, d, LO_F, HI_F) is None or slab(o_cam, d, LO_F, HI_F)[1] < 0.0  # the camera ray misses it
    den = normals @ d
    t = (offsets - normals @ o_cam) / den
    t_in, f_in = np.max(np.where(den < 0.0, t, -np.inf)), np.argmax(np.where(den < 0.0, t, -np.inf))
    assert t_in < np.min(np.where(den > 0.0, t, np.inf)) and t_in > 0.0
    p = o_cam + t_in * d
    w, ti, tt = snell(d, normals[f_in], eta)
    ell = exit_distance(p, w, normals, offsets)
    out = np.zeros(3)
    for f in np.nonzero(normals @ LAMP > offsets)[0]:
        n, c = normals[f], offsets[f]
        pieces = lit_intervals(p, w, ell, LAMP, tri[f], n, c, eta)

        def term(x):
            X = p + x * w
            R, o, k, cos1, cos2, rho, z = fermat_scalar(X, LAMP, n, c, eta)
            e = fresnel_t(math.acos(cos1), math.asin(math.sqrt(1 - cos1**2) / eta), eta) * tube(n @ LAMP - c, z, cos1,
                                                                                                 cos2, rho, eta)
            mu = float((X - R) / k @ -w)
            return ks * oracle.phase("hg", g, mu) * e * np.exp(-kt * (x + k) - kt_out * o - dk * leg(R)[0])

        for lo, hi in pieces:
            cuts = switches(p, w, hi - lo, lambda x: str(leg(fermat_scalar(p + (lo + x) * w, LAMP, n, c, eta)[0])[1]),
                            samples=60) if fog else []
            edges = [lo, *(lo + np.array(sorted(cuts))), hi]
            for a, b in zip(edges, edges[1:]):
                if b > a:
                    out += inten * integrate.quad_vec(term, a, b, epsabs=0.0, epsrel=1e-11, limit=200)[0]
    return math.exp(-kt_out * t_in) * fresnel_t(ti, tt, eta) / eta**2 * out


pytestmark = pytest.mark.slow


def test_a_fog_box_attenuates_the_legs_of_a_512_plane_ball():
    """Volumetric shadows: quadrature (rtol 1e-6) within 1e-6 of the twin with the fog box on the pixels
    compared; its bound finite on every pixel of the image, above the error, at most 10 rtol of the
    value there; not vacuous: the box darkens some pixel compared by more than 5 % against the twin
    without it (before, these legs went unattenuated and the bound was infinite)."""
    ref = np.array([twin_pixel(i, j) for i, j in PIXELS])
    free = np.array([twin_pixel(i, j, fog=False) for i, j in PIXELS])
    assert np.all(ref > 0.0) and np.max(1.0 - ref[:, 1] / free[:, 1]) > 0.05, 1.0 - ref / free
    res = render(prepare(scene_from_text(to_toml(SCENE), SCENE["name"])), "quadrature", {"rtol": 1e-6},
                 RenderOptions(threads=1, volumetric_shadows=True))
    assert np.all(np.isfinite(res.error_bound))
    value = np.array([res.image[j, i] for i, j in PIXELS])
    bound = np.array([res.error_bound[j, i] for i, j in PIXELS])
    err = np.abs(value - ref)
    assert np.all(err <= 1e-6 * ref), err / ref
    assert np.all(err <= bound), err / bound
    assert np.all(bound <= 1e-5 * ref), bound / ref
