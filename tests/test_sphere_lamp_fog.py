"""A sphere lamp above a plate in fog (volumetric shadows): the air-light of each pixel against a twin
built from the geometry alone (numpy and scipy), the floor and the plate black so the pixel is the
air-light alone (and the lamp's own radiance through the fog where the ray meets it):
  A = int_0^T exp(-kt t) ks / (4 pi) L [U(x) - H(x)] dt,  x = o + t d,
U(x) = 2 pi int_0^alpha exp(-kt s(beta)) sin beta dbeta the light the sphere sends to x (s the distance
to the sphere along a direction beta off the axis, sin alpha = R / d), H(x) the part of it the plate
hides: over the plate's points q whose direction from x meets the sphere, exp(-kt s) |q_y - x_y| /
|q - x|^3 dA (the plate lies between the lamp and the points below it), inner integral in z between
the ends of the cone's ellipse on the plate's plane (z = mid + half sin(theta): the ends' square roots
go, Gauss-Legendre), outer in x between the places the ellipse crosses the plate's sides (the same),
along the ray by scipy's quad.
Pixels whose segments the plate never shadows must match within 1e-6 (most with no variance: the
occluders' test cleared them); pixels in the plate's penumbra must be sampled (a variance) and match
within 5 standard errors plus 1e-6. The pilot keeps the coarsest rule (8 rows).
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy import integrate

from raytrace import api
from raytrace.scene.format import scene_from_text

from .conftest import to_toml
from .test_sphere_lamp_surface import camera_rays

R, L = 0.3, 10.0
LAMP = np.array([0.0, 1.0, 0.0])
KA, KS = 0.05, 0.1
KT = KA + KS
Y, X0, X1, Z0, Z1 = 0.45, -0.1, 0.3, -0.1, 0.3  # the plate y = Y over [X0, X1] x [Z0, Z1]
CAMERA = {"position": [1.2, 0.9, 1.8], "look_at": [0.0, 0.0, 0.0], "fov": 30.0, "width": 16, "height": 12}
BLACK_FLOOR = {"primitive": "quad", "corners": [[-20.0, 0.0, 20.0], [20.0, 0.0, 20.0], [20.0, 0.0, -20.0],
                                                [-20.0, 0.0, -20.0]], "reflectance": 0.0}
PLATE = {"primitive": "quad", "corners": [[X0, Y, Z0], [X1, Y, Z0], [X1, Y, Z1], [X0, Y, Z1]], "reflectance": 0.0}
GX, GW = np.polynomial.legendre.leggauss(48)


def scene():
    lamp = {"type": "sphere", "center": LAMP.tolist(), "radius": R, "radiance": L}
    table = {"camera": CAMERA, "shape": [BLACK_FLOOR, PLATE], "light": [lamp],
             "medium": {"sigma_a": [KA] * 3, "sigma_s": [KS] * 3}}
    return scene_from_text(to_toml(table), "fog_plate.toml")


def unoccluded(x) -> float:
    """U(x) (module docstring): beta = alpha (1 - v^2), Gauss-Legendre in v (the square root's end goes)."""
    rel = LAMP - x
    d = float(np.linalg.norm(rel))
    alpha = math.asin(R / d)
    v = 0.5 * (GX + 1.0)
    beta = alpha * (1.0 - v * v)
    s = d * np.cos(beta) - np.sqrt(np.maximum(R * R - (d * np.sin(beta)) ** 2, 0.0))
    return 2.0 * math.pi * float(np.sum(0.5 * GW * 2.0 * alpha * v * np.exp(-KT * s) * np.sin(beta)))


def _arc(lo, hi):
    """Nodes and weights (broadcast over lo, hi) of int_lo^hi by z = mid + half sin(theta), Gauss-Legendre
    in theta."""
    theta = 0.5 * math.pi * GX
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    return mid[..., None] + half[..., None] * np.sin(theta), half[..., None] * GW * 0.5 * math.pi * np.cos(theta)


def hidden(x) -> float:
    """H(x) (module docstring); 0 above the plate and on its plane."""
    h = Y - x[1]
    if h <= 1e-12:  # above the plate, or on it to rounding (a ray that ends on it)
        return 0.0
    rel = LAMP - x
    d = float(np.linalg.norm(rel))
    a = rel / d
    c2 = 1.0 - (R / d) ** 2
    lead = a[2] ** 2 - c2  # < 0: the cone meets the plane y = Y in an ellipse (q = (qx, h, qz) from x)
    breaks = list(np.roots([a[0] ** 2 + lead, 2.0 * a[0] * a[1] * h, (a[1] ** 2 + lead) * h * h]).real)
    for zz in (Z0 - x[2], Z1 - x[2]):
        e = a[1] * h + a[2] * zz
        breaks += list(np.roots([a[0] ** 2 - c2, 2.0 * a[0] * e, e * e - c2 * (h * h + zz * zz)]).real)
    edges = np.array([X0] + sorted(b + x[0] for b in breaks if X0 < b + x[0] < X1) + [X1])
    u, uw = _arc(edges[:-1], edges[1:])
    qx = u.ravel() - x[0]
    s = a[1] * h + a[0] * qx
    disc = (a[2] * s) ** 2 - lead * (s * s - c2 * (h * h + qx * qx))
    r = np.sqrt(np.maximum(disc, 0.0))
    lo = np.maximum(np.minimum((-a[2] * s + r) / lead, (-a[2] * s - r) / lead), Z0 - x[2])
    hi = np.minimum(np.maximum((-a[2] * s + r) / lead, (-a[2] * s - r) / lead), Z1 - x[2])
    ok = (disc > 0.0) & (hi > lo)
    if not ok.any():
        return 0.0
    qz, zw = _arc(lo[ok], hi[ok])
    q = np.stack([np.broadcast_to(qx[ok, None], qz.shape), np.full(qz.shape, h), qz], axis=-1)
    n = np.linalg.norm(q, axis=-1)
    along = (q @ rel) / n
    s = along - np.sqrt(np.maximum(R * R - (d * d - along * along), 0.0))
    return float(np.sum(uw.ravel()[ok, None] * zw * np.exp(-KT * s) * h / n**3))


def first_hit(o, d):
    """(t, whether the lamp) of the ray's first hit: the floor, the plate or the lamp."""
    hits = [(-o[1] / d[1], False)] if d[1] < 0.0 else []
    t = (Y - o[1]) / d[1] if d[1] != 0.0 else -1.0
    p = o + t * d
    if t > 0.0 and X0 <= p[0] <= X1 and Z0 <= p[2] <= Z1:
        hits.append((t, False))
    oc = o - LAMP
    disc = (d @ oc) ** 2 - (oc @ oc - R * R)
    if disc >= 0.0 and -(d @ oc) - math.sqrt(disc) > 0.0:
        hits.append((-(d @ oc) - math.sqrt(disc), True))
    return min(hits)


def twin():
    """(H, W) each pixel's radiance and (H, W) whether the plate shadows any of its segment (at one of 201
    points or of quad's nodes along it); quad to 1e-10 where it does not, 1e-7 where it does (the
    penumbra's pixels are compared within their noise)."""
    h, w = CAMERA["height"], CAMERA["width"]
    out, shadowed = np.zeros((h, w)), np.zeros((h, w), bool)
    for row, col, o, d in camera_rays(CAMERA):
        t_end, lamp = first_hit(o, d)
        seen = [any(hidden(o + t * d) > 0.0 for t in np.linspace(0.0, t_end, 201))]

        def f(t):
            x = o + t * d
            hid = hidden(x)
            seen.append(hid > 0.0)
            return math.exp(-KT * t) * (unoccluded(x) - hid)
        pieces = [0.0, t_end]
        if d[1] != 0.0 and 0.0 < (Y - o[1]) / d[1] < t_end:  # the plane of the plate: H starts or stops
            pieces.insert(1, (Y - o[1]) / d[1])
        rtol = 1e-7 if seen[0] else 1e-10
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", integrate.IntegrationWarning)
            air = sum(integrate.quad(f, a, b, epsabs=0.0, epsrel=rtol, limit=400)[0] for a, b in zip(pieces, pieces[1:]))
        out[row, col] = KS / (4.0 * math.pi) * L * air + (L * math.exp(-KT * t_end) if lamp else 0.0)
        shadowed[row, col] = any(seen)
    return out, shadowed


@pytest.mark.slow
def test_the_air_light_under_a_plate_against_the_twin():
    """16 x 12 pixels (module docstring), `quadrature` rtol 1e-6; the twin takes about a minute (slow:
    `python -m pytest -m slow tests/test_sphere_lamp_fog.py`). Measured: all 56 pixels the plate never
    shadows unsampled, within 5.3e-10; the 136 shadowed ones sampled, |z| <= 1.4 against their standard
    error."""
    ref, shadowed = twin()
    img = api.render(scene(), "quadrature", rtol=1e-6)
    assert img.stats["cubature: rows"] == 8
    value, var = img.array[..., 0], img.variance[..., 0]
    clear = ~shadowed
    assert clear.sum() >= 40 and shadowed.sum() >= 20, (clear.sum(), shadowed.sum())
    rel = np.abs(value / ref - 1.0)
    unsampled = clear & (var == 0.0)
    assert unsampled.sum() >= 0.8 * clear.sum(), (unsampled.sum(), clear.sum())
    assert rel[unsampled].max() <= 1e-6, rel[unsampled].max()
    assert np.all(var[shadowed] > 0.0)
    z = np.abs(value - ref) / (5.0 * np.sqrt(var) + 1e-6 * ref)
    assert z[~unsampled].max() <= 1.0, z[~unsampled].max()
