"""Camera rays within about 1.1 radii of a sphere lamp's pole, in fog: the cap each point of their
segment sees lies between the rows (no cubature node of the pilot's order faces any point of them), yet
it lights the fog. The (ray, sphere) pairs that no row shines on take the rule about the segment where
the occluders' geometry clears it, else the penumbra's samples (rendering/near_emitters.py), so no
order of the rows decides that a segment is unlit. The twin (scipy alone): along the ray
  A = int_0^T exp(-kt t) ks / (4 pi) L V(|x - c|) dt,  x = o + t d,
V(d) the light the cap seen from distance d sends, over r the distance to its points (d^2 = ... r^2 =
d^2 + R^2 - 2 d R cos theta): V(d) = (pi / d) int_{d-R}^{sqrt(d^2 - R^2)} exp(-kt r) ((d^2 - R^2) / r^2 - 1)
dr (2 pi (1 - cos alpha) in the vacuum), its first term in u = 1 / r; plus the lamp's radiance through
the fog where the ray ends on it. A black ceiling just above the camera (rays that end on it) hides
nothing; a black floor through the lamp's lower half hides nothing the segments see either, but it
meets the hull of each segment and the ball, so with volumetric shadows those pairs are sampled.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import integrate

from raytrace import api
from raytrace.lights import area
from raytrace.scene.format import scene_from_text

from .conftest import to_toml
from .test_sphere_lamp_surface import camera_rays

R, L = 0.3, 10.0
LAMP = np.array([0.0, 1.0, 0.0])
KA, KS = 0.05, 0.1
KT = KA + KS
DOWN = {"position": (LAMP + [0.0, 1.1 * R, 1e-3]).tolist(), "look_at": LAMP.tolist(), "fov": 30.0, "width": 4,
        "height": 3}  # every ray ends on the lamp near its pole
UP = {"position": (LAMP + [0.0, 1.05 * R, 0.0]).tolist(), "look_at": (LAMP + [0.0, 2.0 * R, 1e-3]).tolist(),
      "fov": 60.0, "width": 4, "height": 3}  # every ray ends on the ceiling
CEILING_Y = float(LAMP[1] + 1.12 * R)
FLOOR_Y = float(LAMP[1] - 0.9 * R)


def _plane(y: float) -> dict:
    return {"primitive": "quad", "corners": [[-20.0, y, 20.0], [20.0, y, 20.0], [20.0, y, -20.0], [-20.0, y, -20.0]],
            "reflectance": 0.0}


def scene(camera, shapes=()):
    lamp = {"type": "sphere", "center": LAMP.tolist(), "radius": R, "radiance": L}
    table = {"camera": camera, "shape": list(shapes), "light": [lamp],
             "medium": {"sigma_a": [KA] * 3, "sigma_s": [KS] * 3}}
    return scene_from_text(to_toml(table), "unfaced.toml")


def cap_light(d: float, kt: float = KT) -> float:
    """V(d) (module docstring)."""
    a, b = d - R, math.sqrt(d * d - R * R)
    first = (d * d - R * R) * integrate.quad(lambda u: math.exp(-kt / u), 1.0 / b, 1.0 / a, epsabs=0.0,
                                             epsrel=1e-13)[0]
    second = b - a if kt == 0.0 else -math.exp(-kt * a) * math.expm1(-kt * (b - a)) / kt
    return math.pi / d * (first - second)


def test_cap_light_in_the_vacuum():
    """V's closed form where kt is 0: the solid angle of the cap, 2 pi (1 - sqrt(1 - R^2 / d^2))."""
    for d in (1.0001 * R, 1.1 * R, 3.0 * R):
        assert abs(cap_light(d, 0.0) - 2.0 * math.pi * (1.0 - math.sqrt(1.0 - (R / d) ** 2))) < 1e-9


def rays(camera):
    """(row, column, origin, direction, t of the end, whether it ends on the lamp) per pixel."""
    for row, col, o, d in camera_rays(camera):
        oc = o - LAMP
        b = d @ oc
        disc = b * b - (oc @ oc - R * R)
        t_lamp = -b - math.sqrt(disc) if disc >= 0.0 and b < 0.0 else math.inf
        t_ceiling = (CEILING_Y - o[1]) / d[1] if d[1] > 0.0 else math.inf
        yield row, col, o, d, min(t_lamp, t_ceiling), t_lamp < t_ceiling


def twin(camera):
    """(H, W) each pixel's radiance (module docstring), quad to 1e-11."""
    out = np.zeros((camera["height"], camera["width"]))
    for row, col, o, d, t_end, lamp in rays(camera):
        air = integrate.quad(lambda t: math.exp(-KT * t) * cap_light(float(np.linalg.norm(o + t * d - LAMP))), 0.0,
                             t_end, epsabs=0.0, epsrel=1e-11, limit=200)[0]
        out[row, col] = KS / (4.0 * math.pi) * L * air + (L * math.exp(-KT * t_end) if lamp else 0.0)
    return out


def faced(camera, rows: int) -> int:
    """How many of the camera's rays a node of the sphere's rule of `rows` rows (2 n^2) faces somewhere
    along them (2,001 points each)."""
    order = round(math.sqrt(rows / 2))
    z, _ = area.gauss_legendre(order)
    z = 2.0 * z - 1.0
    phi = 2.0 * math.pi * (np.arange(2 * order) + 0.5) / (2 * order)
    s = np.sqrt(1.0 - z * z)
    normals = np.stack([np.outer(s, np.cos(phi)), np.repeat(z[:, None], 2 * order, 1), np.outer(s, np.sin(phi))],
                       axis=-1).reshape(-1, 3)
    count = 0
    for _, _, o, d, t_end, _ in rays(camera):
        x = o + np.linspace(0.0, t_end, 2001)[:, None] * d - LAMP
        count += bool(np.any(x @ normals.T > R))
    return count


def _check_rule(img, camera, ref):
    """No row of the pilot's order faces any ray, every ray takes the rule (no variance), converged and
    within 1e-6 of the twin."""
    assert faced(camera, img.stats["cubature: rows"]) == 0
    assert img.stats["cubature: rays near an emitter"] == camera["width"] * camera["height"]
    assert img.stats["cubature: rays near an emitter not converged"] == 0
    assert img.variance is None or not np.any(img.variance)
    err = np.abs(img.array[..., 0] - ref) / ref
    assert err.max() < 1e-6, err.max()


def test_rays_ending_on_the_lamp_between_its_rows():
    """Looking down at the pole from 1.1 radii, `quadrature` rtol 1e-6, without volumetric shadows: the
    rule on every ray, within 1e-6 of the twin (measured 4.2e-8; the rows alone left out the air-light,
    1.1e-3 of the pixel)."""
    img = api.render(scene(DOWN), "quadrature", rtol=1e-6, volumetric_shadows=False)
    _check_rule(img, DOWN, twin(DOWN))


def test_rays_beside_the_lamp_between_its_rows():
    """Looking up from 1.05 radii above the centre to a black ceiling, volumetric shadows on, the
    ceiling clearing every segment: the rule on every ray (the rows' states say none shines on it),
    within 1e-6 of the twin (measured 3.4e-10), where the air-light is the whole pixel (the rows alone:
    black)."""
    img = api.render(scene(UP, [_plane(CEILING_Y)]), "quadrature", rtol=1e-6)
    _check_rule(img, UP, twin(UP))


def test_sampled_where_the_geometry_may_hide_the_cap():
    """The same under a floor through the lamp's lower half (it meets the hull of each segment and the
    ball, though it hides nothing the segments see): every pixel sampled (a variance) and within 5
    standard errors plus 1e-6 of the twin (measured 1.6; samples of the whole sphere, which rarely met
    the cap the segments see, were up to 10 standard errors off)."""
    img = api.render(scene(UP, [_plane(CEILING_Y), _plane(FLOOR_Y)]), "quadrature", rtol=1e-6)
    assert faced(UP, img.stats["cubature: rows"]) == 0
    ref = twin(UP)
    value, var = img.array[..., 0], img.variance[..., 0]
    assert np.all(ref > 1e-4), ref.min()
    assert np.all(var > 0.0)
    z = np.abs(value - ref) / (5.0 * np.sqrt(var) + 1e-6 * ref)
    assert z.max() <= 1.0, z.max()


def test_seen_cap_holds_all_a_segment_sees():
    """`Ball.seen_cap` against brute force: on 300 random segments outside the sphere (some ending on it,
    some far), every normal of a 20,000-point Fibonacci sphere that one of 400 points of the segment sees
    lies in the cap; the cap is not the whole sphere for segments within 3 radii; `sample_cap`'s points lie
    on the sphere, its normals in the cap, and its density integrates to 1 over the cap's area."""
    from raytrace.lights.sphere_rule import Ball
    rng = np.random.default_rng(7)
    ball = Ball(LAMP, R)
    k = np.arange(20000) + 0.5
    z = 1.0 - 2.0 * k / 20000
    phi = math.pi * (1.0 + 5.0 ** 0.5) * k
    fib = np.stack([np.sqrt(1.0 - z * z) * np.cos(phi), z, np.sqrt(1.0 - z * z) * np.sin(phi)], axis=1)
    o = LAMP + R * (1.0 + 3.0 * rng.random((300, 1)) ** 2) * _unit(rng.normal(size=(300, 3)))
    d = _unit(rng.normal(size=(300, 3)))
    b = np.einsum("ij,ij->i", d, o - LAMP)
    disc = b * b - (np.einsum("ij,ij->i", o - LAMP, o - LAMP) - R * R)
    hit = np.where((disc >= 0.0) & (b < 0.0), -b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
    tmax = np.minimum(hit, R * 4.0 * rng.random(300))
    axis, h = ball.seen_cap(o, d, tmax)
    assert np.all(h[np.linalg.norm(o - LAMP, axis=1) + tmax < 1.5 * R] < 2.0)
    for i in range(300):
        x = o[i] + np.linspace(0.0, tmax[i], 400)[:, None] * d[i] - LAMP
        seen = np.any(x @ fib.T > R, axis=0)
        assert np.all(1.0 - fib[seen] @ axis[i] <= h[i]), i
    u, v = rng.random((300, 50)), rng.random((300, 50))
    points, normals, density = ball.sample_cap(axis, h, u, v)
    assert np.allclose(np.linalg.norm(points - LAMP, axis=1), R, rtol=1e-12, atol=0.0)
    assert np.all(1.0 - np.einsum("pkj,pj->pk", normals.reshape(300, 50, 3), axis) <= h[:, None] + 1e-12)
    assert np.allclose(density.reshape(300, 50)[:, 0] * 2.0 * math.pi * R * R * np.minimum(h, 2.0), 1.0)


def _unit(a):
    return a / np.linalg.norm(a, axis=1)[:, None]
