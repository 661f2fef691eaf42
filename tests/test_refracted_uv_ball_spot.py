"""A spot's refracted paths into the 512-plane glass UV ball (32 segments), its beam's edge across the
ball: the cone levels' crossings along a refracted path (media/slab.py `refracted_cuts`, `_cone_crossings`)
and the edges where a refraction point leaves its face, with the bound `quadrature` reports there.

The twin uses the geometry alone: tests/test_refracted_mesh_faces.py's (each triangle's Fermat path in the
plane of incidence, counted where the refraction point lies in the triangle, the ray tube's irradiance)
times the spot's smoothstep falloff of the direction the light leaves in, scipy quad cut where the
triangle's lit set or either cone level's side changes (each bisected on its indicator). Slow (the twin's
Fermat paths over the ball's triangles, about a minute a pixel): `python -m pytest -m slow
tests/test_refracted_uv_ball_spot.py`.
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
from .test_bounded_media import fresnel_t, snell
from .test_refracted_mesh_faces import exit_distance, fermat_scalar, lit_intervals
from .test_refracted_point_light import smoothstep, spot_terms, switches, tube
from .test_refracted_uv_ball_sun import uv_ball, uv_triangles

SPOT = {"type": "spot", "position": [2.0, 2.0, 1.0], "look_at": [0.0, 0.0, 0.0], "intensity": 5.0,
        "cone_angle": 12.0, "falloff_start": 6.0}
SCENE = uv_ball(32, 32, 24) | {"medium": {"sigma_a": 0.02}, "light": [SPOT]}
PIXELS = [(17, 1), (16, 2), (25, 12), (24, 14), (21, 5)]


def spot_segment(p, w, ell, geometry):
    """The spot's single scattering (3,) over the inside segment p + x w, x in [0, ell]: each triangle
    whose plane the light is outside of, on Fermat's path where the refraction point lies in the
    triangle, times the falloff of the direction (R - L) / |R - L| the light leaves in."""
    tri, normals, offsets = geometry
    inner = SCENE["shape"][0]["interior"]
    eta, g = inner["ior"], inner["phase"]["g"]
    ks = np.array(inner["sigma_s"], float)
    kt = np.array(inner["sigma_a"], float) + ks
    kt_out = SCENE["medium"]["sigma_a"]
    L, spot = np.array(SPOT["position"], float), spot_terms(SPOT)
    out = np.zeros(3)
    for f in np.nonzero(normals @ L > offsets)[0]:
        n, c = normals[f], offsets[f]

        def leaving(x):  # on the face's plane (a lit interval's end at the entry face) the path is straight
            X = p + x * w
            R = X if c - n @ X <= 0.0 else fermat_scalar(X, L, n, c, eta)[0]
            return float((R - L) @ spot[0]) / np.linalg.norm(R - L)

        def side(x):
            cos = leaving(x)
            return cos > spot[1], cos > spot[2]

        def term(x):
            X = p + x * w
            R, o, k, cos1, cos2, rho, z = fermat_scalar(X, L, n, c, eta)
            e = fresnel_t(math.acos(cos1), math.asin(math.sqrt(1 - cos1**2) / eta), eta) * tube(n @ L - c, z, cos1,
                                                                                                 cos2, rho, eta)
            mu = float((X - R) / k @ -w)
            fall = smoothstep(float((R - L) @ spot[0]) / o, spot[1], spot[2])
            return ks * oracle.phase("hg", g, mu) * fall * e * np.exp(-kt * (x + k) - kt_out * o)

        for lo, hi in lit_intervals(p, w, ell, L, tri[f], n, c, eta):
            cuts = [lo + x for x in switches(p + lo * w, w, hi - lo, lambda x: side(lo + x))]
            edges = [lo, *cuts, hi]
            out += SPOT["intensity"] * sum(integrate.quad_vec(term, a, b, epsabs=0.0, epsrel=1e-11, limit=200)[0]
                                           for a, b in zip(edges[:-1], edges[1:]))
    return out


def twin_pixel(geometry, i, j):
    """Pixel (i, j)'s radiance (3,): the camera ray refracted into the ball, the spot's single scattering
    along it, the entry's Fresnel transmittance and radiance scaling, the outside's attenuation."""
    _, normals, offsets = geometry
    eta, kt_out = SCENE["shape"][0]["interior"]["ior"], SCENE["medium"]["sigma_a"]
    o_cam, d = oracle.camera_ray(SCENE["camera"], i, j)
    den = normals @ d
    t = (offsets - normals @ o_cam) / den
    t_in, f_in = np.max(np.where(den < 0.0, t, -np.inf)), np.argmax(np.where(den < 0.0, t, -np.inf))
    assert 0.0 < t_in < np.min(np.where(den > 0.0, t, np.inf))
    p = o_cam + t_in * d
    w, ti, tt = snell(d, normals[f_in], eta)
    out = spot_segment(p, w, exit_distance(p, w, normals, offsets), geometry)
    return math.exp(-kt_out * t_in) * fresnel_t(ti, tt, eta) / eta**2 * out


@pytest.mark.slow
def test_the_spot_into_the_512_plane_ball_against_the_twin():
    """Pixels across the beam's edge (two at the top of the ball where the cone levels cross refracted
    paths at a glance, two dim ones at its side) and one in the beam, rendered alone with `quadrature` at
    rtol 1e-6: within 1e-6 of the twin, every bound finite and above the error, the median bound at
    most 10 rtol of the value."""
    geometry = uv_triangles(SCENE)[:3]
    prep = prepare(scene_from_text(to_toml(SCENE), SCENE["name"]))
    ratios = []
    for i, j in PIXELS:
        ref = twin_pixel(geometry, i, j)
        res = render(prep, "quadrature", {"rtol": 1e-6}, RenderOptions(threads=1, crop=(i, j, i + 1, j + 1)))
        value, bound = res.image.reshape(-1, 3)[-1], res.error_bound.reshape(-1, 3)[-1]
        err = np.abs(value - ref)
        assert np.all(ref > 0.0)
        assert np.all(np.isfinite(bound)) and np.all(err <= bound), ((i, j), err, bound)
        assert np.all(err <= 1e-6 * ref), ((i, j), err / ref)
        ratios.append(bound / ref)
    assert np.median(ratios) <= 1e-5, ratios
