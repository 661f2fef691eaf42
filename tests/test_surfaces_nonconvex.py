"""Plain surfaces inside a refractive shape that is not convex (interiors/surfaces.py `_lit_through_triangles`,
`_triangle_beams`) against a twin from the triangles alone.

The shape is the glass U of tests/test_nonconvex_refraction.py (ior 1.5, an absorbing interior that does not
scatter, so that a pixel that sees a surface inside holds that surface's term alone) with a floor inside its base
and a plate inside its right arm that shadows part of the floor, lit by a lamp or a spot above it (in an absorbing
outside medium) or by the sun from behind (test_nonconvex_sun's). The twin reads the OBJ's triangles and the quads'
corners and knows nothing of the renderer: Moller-Trumbore in float64 for every crossing; the camera ray refracted
in at its first triangle (skipped where its mirror reflection meets the U again) to the first quad it meets inside;
there the surface term rho / pi sum E cos_s exp(-sigma_t k - sigma_out o) over every triangle whose Fermat point
(scipy `brentq` on Snell's law) lies on it and whose legs meet no other triangle (test_nonconvex_refraction.paths_of)
nor quad, E the lamp's intensity times the spot's falloff times the ray tube's irradiance by central differences;
for the sun, every triangle's beam whose path back first
meets that triangle and whose leg from there toward the sun meets none (test_nonconvex_sun.beams), irradiance
T cos_i / cos_t, and no quad on the path back. The pixel: exp(-sigma_out t0) T / eta^2 exp(-sigma_t ell) times it.
Before: point and spot light were refused here ("lies inside shape[0], whose interior is refractive ... and not
convex") and the sun came through the plane of the face the camera ray entered by alone.
"""
import math

import numpy as np
import pytest

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import oracle
from .conftest import to_toml
from .test_inside_paths import KA, KS, KT_OUT, u_obj
from .test_nonconvex_refraction import ETA, entering, first, paths_of, transmittance
from .test_nonconvex_sun import SUN, beams

KT = KA + KS  # the glass's absorption (the attenuation of test_nonconvex_refraction.paths_of), the outside's KT_OUT with a lamp
RHO = 0.6
FLOOR = [[-0.9, -0.75, -0.4], [0.9, -0.75, -0.4], [0.9, -0.75, 0.4], [-0.9, -0.75, 0.4]]  # in the base
PLATE = [[0.5, 0.0, -0.4], [0.9, 0.0, -0.4], [0.9, 0.0, 0.4], [0.5, 0.0, 0.4]]  # in the right arm
QUADS = np.array([[c[0], c[1], c[2]] for c in (FLOOR, PLATE)] + [[c[0], c[2], c[3]] for c in (FLOOR, PLATE)], float)
LAMP = {"type": "point", "position": [0.15, 1.3, 0.1], "intensity": 3.0}
SPOT = LAMP | {"type": "spot", "look_at": [0.3, -0.75, 0.1], "cone_angle": 12.0, "falloff_start": 6.0}
LIGHTS = {"lamp": LAMP, "spot": SPOT, "sun": SUN}
VIEW = {"position": [0.25, 1.4, 3.0], "look_at": [0.0, -0.6, 0.0], "fov": 36.0, "width": 24, "height": 16, "spp": 1}


def quad_hit(o, d):
    """(t, normal) of the ray o + t d on the nearest quad (t > 1e-9; inf where none)."""
    t, u, v, det = oracle.triangle_hits(QUADS, o, d)
    with np.errstate(invalid="ignore"):
        t = np.where((np.abs(det) > 1e-14) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9), t, np.inf)
    k = int(np.argmin(t))
    n = np.cross(QUADS[k, 1] - QUADS[k, 0], QUADS[k, 2] - QUADS[k, 0])
    return t[k], n / np.linalg.norm(n)


def radiance(X, n, light):
    """The surface term at X (facing normal n) inside the U."""
    out = np.zeros(3)
    if light["type"] == "directional":
        for _, d, e, s in beams(X):
            cos_s = -float(d @ n)
            if cos_s > 0 and not quad_hit(X, -d)[0] < s:
                out += RHO / math.pi * e * cos_s * np.exp(-KT * s)
        return out
    for _, t, v in paths_of(X, light):  # t: the direction of travel inside, v: E exp(-sigma_t k - sigma_out o)
        cos_s = -float(t @ n)
        if cos_s > 0 and not quad_hit(X, -t)[0] < first(X, -t)[0]:  # no quad before the path's triangle
            out += RHO / math.pi * v * cos_s
    return out


def twin_pixel(light, i, j):
    """The pixel's radiance (3,) where the camera ray refracted into the U meets a quad first, else None (also
    where its mirror reflection meets the U again)."""
    o, d = oracle.camera_ray(VIEW, i, j)
    hit = entering(o, d)
    if hit is None:
        return None
    t0, n, P, w = hit
    ell, m = quad_hit(P, w)
    if not ell < first(P, w)[0]:
        return None
    kt_out = 0.0 if light["type"] == "directional" else KT_OUT
    return (math.exp(-kt_out * t0) * transmittance(-float(d @ n), ETA) / ETA ** 2 * np.exp(-KT * ell)
            * radiance(P + ell * w, m if m @ w < 0 else -m, light))


def scene(light):
    obj = u_obj()
    u = {"primitive": "triangles",
         "vertices": [list(map(float, line.split()[1:])) for line in obj.splitlines() if line.startswith("v ")],
         "faces": [[int(k) - 1 for k in line.split()[1:]] for line in obj.splitlines() if line.startswith("f ")],
         "interior": {"sigma_a": KT.tolist(), "sigma_s": 0.0, "ior": ETA}}
    sc = {"camera": VIEW, "shape": [u, {"primitive": "quad", "corners": FLOOR, "reflectance": RHO},
                                    {"primitive": "quad", "corners": PLATE, "reflectance": RHO}], "light": [light]}
    if light["type"] != "directional":
        sc["medium"] = {"sigma_a": KT_OUT}
    return prepare(scene_from_text(to_toml(sc), "u_floor"))


@pytest.mark.parametrize("name", sorted(LIGHTS))
def test_surfaces_inside_a_glass_u_match_the_twin(name):
    """Every pixel whose camera ray meets the floor or the plate inside within 1e-6 of the twin (lamp and sun
    measured below 1e-9), the image the same for every method (nothing scatters); lit through several triangles
    (the arms' tops and inner faces, the notch's floor, the back) and shadowed by the plate and by the U itself:
    pixels on the floor both lit and dark. Before: refused (lamp, spot), the entry plane's beam (sun)."""
    light = LIGHTS[name]
    prep = scene(light)
    img = render(prep, "quadrature", {"rtol": 1e-6}, RenderOptions(threads=1)).image
    seen = lit = 0
    for j in range(VIEW["height"]):
        for i in range(VIEW["width"]):
            ref = twin_pixel(light, i, j)
            if ref is None:
                continue
            seen += 1
            lit += bool(np.all(ref > 0))
            assert np.allclose(img[j, i], ref, rtol=1e-6, atol=1e-300), (i, j, img[j, i], ref)
    assert seen >= 30 and lit >= 10 and seen - lit >= {"lamp": 1, "spot": 5, "sun": 1}[name], (seen, lit)
    march = render(prep, "raymarch", {"steps": 4}, RenderOptions(threads=1)).image
    assert np.array_equal(march, img)


@pytest.mark.parametrize("light", ["lamp", "spot"])
def test_the_rock_in_the_dented_box_is_lit(light):
    """tests/test_bounded_media.py's rock in a water box with its top dented (not convex), refused there before
    under a lamp and a spot: rendered, its pixels lit (the values are the U's twin's business), the same for raymarch
    (the water made not to scatter: the lit pixels are the rock's)."""
    from .test_bounded_media import ABOVE, rock_in_dented_box
    from .test_bounded_media import LAMP as ROCK_LAMP

    sc = rock_in_dented_box({"lamp": ROCK_LAMP, "spot": ABOVE}[light])
    sc["shape"][0]["interior"]["sigma_s"] = 0.0  # the pixels lit are the rock's
    sc["camera"].update(look_at=[0.0, -0.6, 0.0], fov=16.0, width=24, height=16)
    prep = prepare(scene_from_text(to_toml(sc), "rock"))
    img = render(prep, "quadrature", {}, RenderOptions(threads=1)).image
    assert np.count_nonzero(img[..., 0] > 0) >= 20, img[..., 0]
    assert np.array_equal(render(prep, "raymarch", {"steps": 4}, RenderOptions(threads=1)).image, img)
