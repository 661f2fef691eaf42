"""A point light within a few roundings of a face's plane (media/slab.py `grazing_bound`): the face's whole
term is bounded, not its breaks (whose isolation needs the light's height above the plane), and a face
that `refracting_faces` leaves out by its computed height while the exact height may be positive is
bounded the same way (`_left_out`).

The twin: the face's exact term for a light at the largest height the bound allows, built from the
geometry alone (Fermat's path by brentq in the plane of incidence, tests/test_refracted_mesh_faces.py
`fermat_scalar`; the ray tube's irradiance, tests/test_refracted_point_light.py `tube`; Fresnel's T),
integrated by scipy quad over the segment, is below the bound; the bound is below 1e-6 of the same
face's term for a light at unit height.
"""
import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.media import slab
from raytrace.media.phase import HG, phase_value

from .test_bounded_media import fresnel_t
from .test_refracted_mesh_faces import fermat_scalar
from .test_refracted_point_light import tube

PLANE = np.array([[0.0, 0.0, 1.0, 0.0]])  # the face's plane z = 0, the shape below it


def face_row(p, w, light, floor):
    geo = np.zeros(slab.GEO_COLUMNS)
    geo[:3], geo[3:6], geo[6:9] = p, w, light
    geo[12:14], geo[17] = slab.NO_SPOT[3:5], slab.NO_SPOT[5]
    rows = np.empty((1, slab.FACE_COLUMNS))
    m = slab.refracting_faces(geo, PLANE, 0.0, 0.0, 0.0, 0.0, slab.NO_SPOT, rows, floor)
    return rows[0] if m else None


def twin(p, w, light, end, eta, g):
    """∫_0^end of the face's exact term (ks = 1, no attenuation) for the light `light`."""
    n, c = PLANE[0, :3], 0.0

    def term(x):
        X = p + x * w
        if not n @ X < c:
            return 0.0
        R, o, k, cos1, cos2, rho, z = fermat_scalar(X, light, n, c, eta)
        t = fresnel_t(math.acos(cos1), math.asin(math.sqrt(1.0 - cos1**2) / eta), eta)
        mu = float((X - R) / k @ -w)
        return phase_value(HG, g, mu) * t * tube(light[2], z, cos1, cos2, rho, eta)

    return integrate.quad(term, 0.0, end, epsabs=0.0, epsrel=1e-4, limit=200)[0]


@pytest.mark.parametrize("eta", [1.33, 1.5])
@pytest.mark.parametrize("height", [1e-14, 0.0, -1e-13])
def test_the_grazing_bound_holds(eta, height):
    rng = np.random.default_rng(7)
    dc = 1e-11
    for _ in range(4):
        p = np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), -rng.uniform(0.0, 0.3)])
        w = rng.normal(size=3)
        w[2] = -abs(w[2]) - 0.3
        w /= np.linalg.norm(w)
        end = rng.uniform(0.2, 0.8)
        light = np.array([3.0 + rng.uniform(0.0, 1.0), rng.uniform(-1.0, 1.0), height])
        row = face_row(p, w, light, -1e-9)
        assert row is not None and row[2] == height
        size = np.linalg.norm(p) + end + np.linalg.norm(light)
        mags = (np.linalg.norm(p), np.linalg.norm(light), np.linalg.norm(light - p), size)
        bound = slab.grazing_bound(row[0], row[1], row[2], row[3], row[4], end, 1.0, HG, 0.3, eta,
                                   np.array([0.0, dc]), mags)
        top = max(height, 0.0) + dc  # the exact light may be this high
        exact = twin(p, w, light + np.array([0.0, 0.0, top - height]), end, eta, 0.3)
        assert 0.0 < exact <= bound, (exact, bound)
        assert bound < 1e-6 * twin(p, w, light + np.array([0.0, 0.0, 1.0 - height]), end, eta, 0.3)


def test_no_bound_where_the_refraction_point_may_reach_the_light():
    """o >= rho - z / sqrt(eta^2 - 1) is the bound's only hold on the outside leg: where it is not
    positive the bound is infinite."""
    p, w = np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, -1.0])
    row = face_row(p, w, np.array([0.5, 0.0, 0.0]), -1e-9)
    mags = (1.0, 0.5, 1.2, 3.0)
    assert slab.grazing_bound(row[0], row[1], row[2], row[3], row[4], 0.5, 1.0, HG, 0.3, 1.5, np.zeros(2),
                              mags) == math.inf


def test_a_lamp_in_a_faces_plane_keeps_the_bound_finite():
    """A 512-plane UV sphere of water under a lamp that lies in the plane of one of its faces (to
    1e-15): that face is kept on some segments, whose bound was infinite before `grazing_bound`
    (the breaks' isolation needs the lamp's height); quadrature's bound is finite on every pixel."""
    from raytrace.interiors import shapes
    from raytrace.options import RenderOptions
    from raytrace.rendering.renderer import prepare, render
    from raytrace.scene.format import scene_from_text

    from .conftest import to_toml
    from .test_interiors_scale import SPHERE

    inner = SPHERE["shape"][0]["interior"] | {"ior": 1.33}
    scene = {**SPHERE, "camera": SPHERE["camera"] | {"width": 8, "height": 6},
             "shape": [SPHERE["shape"][0] | {"segments": 32, "interior": inner}]}
    prep = prepare(scene_from_text(to_toml(scene), "uv32"))
    planes = shapes.refracting_planes(prep, 0)
    lamp = np.array(SPHERE["light"][0]["position"], float)
    assert len(planes) == 512 and np.min(np.abs(planes[:, :3] @ lamp - planes[:, 3])) < 1e-15
    res = render(prep, "quadrature", {}, RenderOptions(threads=1))
    assert np.all(np.isfinite(res.error_bound))
