"""Writes tests/data/surfaces_sphere_twins.json, the twin of tests/test_surfaces_sphere.py: surfaces inside a glass
exact sphere (ior 1.5) sunk into a floor, lit by a lamp and by a spot outside it, from the geometry alone in 30-digit
mpmath (no project code; `python -m tests.make_surfaces_sphere_twins`, about 45 s CPU).

Fermat's paths from the light L to an inside point X lie in the plane of L, the centre c and X (the normal at the
refraction point P lies in it): P(theta) = c + R (cos theta ez + sin theta ey), the optical path F(theta) = |P - L|
+ eta |X - P| stationary, F'(theta) = 0 bracketed on NODES nodes of the lit arc and solved by mpmath's
bisection-secant (`anderson`). Each root is checked against Snell's law in 3-D (the vector form refracts (P - L) / o
at the normal (P - c) / R into the direction of X - P, to 1e-25). The irradiance at X is the ray tube's by flux
conservation: the light's I cos_i dA / o^2 through the patch dA of the sphere about P (P(u, v) = c + R normalize(n +
u e1 + v e2)) times Fresnel's unpolarised T, over the tube's section at X across the ray, |(Y_u x Y_v) . t| du dv
with Y = P + s t (t refracted at P(u, v), s = |X - P| fixed), the partial derivatives by central differences of step
1e-10 (their error about 1e-20). A spot's falloff is pbrt's smoothstep in the cosine of (P - L) / o to its axis.

`points`: each path at inside points (floor points and some below it, where three paths reach a point) per unit
intensity: E F, s, o and the unit direction t of travel inside. `pixels`: the camera's pixels whose ray (its centre's,
`camera_ray` in float64) enters the sphere and first meets, inside, the floor or the plate held inside (its mirror
reflection meeting no quad): exp(-kt_out t0) T / eta^2 exp(-kt ell) rho / pi sum I E F cos_s exp(-kt s - kt_out o)
over the paths whose legs meet no quad (the floor, the plate inside, the plate outside between the light and the
sphere), per channel.
"""
from __future__ import annotations

import json
from pathlib import Path

import mpmath as mp
import numpy as np

from . import oracle

mp.mp.dps = 30
CENTRE, RADIUS, ETA = [0.0, 0.4, 0.0], 1.0, 1.5
KT, KT_OUT, RHO = [0.1, 0.2, 0.3], [0.05, 0.04, 0.03], 0.6
FLOOR = [[-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0], [-3.0, 0.0, -3.0]]
PLATE_IN = [[-0.55, 0.5, -0.3], [-0.15, 0.5, -0.3], [-0.15, 0.5, 0.3], [-0.55, 0.5, 0.3]]  # inside the sphere
PLATE_OUT = [[0.3, 2.2, -0.1], [0.8, 2.2, -0.1], [0.8, 2.2, 0.5], [0.3, 2.2, 0.5]]  # between the lamp and the sphere
LAMP = {"type": "point", "position": [0.4, 3.0, 0.3], "intensity": [5.0, 4.0, 3.0]}
SPOT = LAMP | {"type": "spot", "look_at": [0.1, 0.0, 0.1], "cone_angle": 22.0, "falloff_start": 14.0}
LIGHTS = {"lamp": LAMP, "spot": SPOT}
VIEW = {"position": [0.0, 2.2, 3.2], "look_at": [0.0, 0.1, 0.0], "fov": 36.0, "width": 24, "height": 16, "spp": 1}
NODES = 1200
POINTS = [[-0.278, 0.0, 0.056], [-0.509, 0.0, -0.048], [0.365, 0.0, 0.155], [0.2, 0.0, -0.268], [0.08, 0.0, -0.306],
          [-0.6, 0.0, 0.3], [0.161, -0.363, 0.344], [0.124, -0.408, -0.517], [-0.423, -0.413, 0.108],
          [0.115, -0.23, 0.426]]  # on the floor (the sixth in the dark beyond the marginal rays), and below it
PATH = Path(__file__).parent / "data" / "surfaces_sphere_twins.json"


def vec(x):
    return np.array([mp.mpf(v) for v in x], dtype=object)


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def norm(a):
    return mp.sqrt(dot(a, a))


def cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]], dtype=object)


def fresnel_t(cos_i, eta):
    """Unpolarised Fresnel transmittance from index 1 into eta at incidence cosine cos_i."""
    cos_t = mp.sqrt(1 - (1 - cos_i ** 2) / eta ** 2)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 1 - (rs ** 2 + rp ** 2) / 2


def snell(i, n, eta):
    """The unit direction of the unit i refracted at the unit normal n (n . i < 0) into index eta, and cos_i."""
    cos_i = -dot(i, n)
    cos_t = mp.sqrt(1 - (1 - cos_i ** 2) / eta ** 2)
    return i / eta + (cos_i / eta - cos_t) * n, cos_i


def falloff(light, direction):
    """pbrt's smoothstep falloff of a spot toward the unit direction (1 for a point light)."""
    if light["type"] != "spot":
        return mp.mpf(1)
    axis = vec(light["look_at"]) - vec(light["position"])
    c = dot(direction, axis) / norm(axis)
    cos_end, cos_start = mp.cos(mp.radians(light["cone_angle"])), mp.cos(mp.radians(light["falloff_start"]))
    if c >= cos_start:
        return mp.mpf(1)
    if c <= cos_end:
        return mp.mpf(0)
    t = (c - cos_end) / (cos_start - cos_end)
    return t * t * (3 - 2 * t)


def paths(X, light):
    """[(E F per unit intensity, s, o, t, P)] of the light's refracted paths to the inside point X."""
    c, L, eta = vec(CENTRE), vec(light["position"]), mp.mpf(ETA)
    ez = (L - c) / norm(L - c)
    v = X - c
    perp = v - dot(v, ez) * ez
    ey = perp / norm(perp)
    span = mp.acos(RADIUS / norm(L - c))

    def at(th):
        return c + RADIUS * (mp.cos(th) * ez + mp.sin(th) * ey)

    def slope(th):
        p = at(th)
        dp = RADIUS * (-mp.sin(th) * ez + mp.cos(th) * ey)
        return dot(p - L, dp) / norm(p - L) - eta * dot(X - p, dp) / norm(X - p)

    with mp.workdps(15):
        nodes = [span * (2 * k / NODES - 1) for k in range(1, NODES)]
        values = [slope(th) for th in nodes]
    out = []
    for a, b, fa, fb in zip(nodes, nodes[1:], values, values[1:]):
        if fa * fb > 0:
            continue
        th = mp.findroot(slope, (a, b), solver="anderson")
        p = at(th)
        o, s = norm(p - L), norm(X - p)
        t, cos_i = snell((p - L) / o, (p - c) / RADIUS, eta)
        assert cos_i > 0 and norm(cross(t, (X - p) / s)) < 1e-25 and dot(t, X - p) > 0, (X, th)
        out.append((_tube(p, L, s, eta) * falloff(light, (p - L) / o), s, o, t, p))
    return out


def _tube(p, L, s, eta):
    """T cos_i dA / (o^2 |(Y_u x Y_v) . t|) at the distance s along the ray refracted at p (module docstring)."""
    c = vec(CENTRE)
    n = (p - c) / RADIUS
    e1 = cross(n, vec([0.3, 0.7, 0.2]))
    e1 = e1 / norm(e1)
    e2 = cross(n, e1)

    def point(u, w):
        m = n + u * e1 + w * e2
        return c + RADIUS * m / norm(m)

    def ray(u, w):
        q = point(u, w)
        return q + s * snell((q - L) / norm(q - L), (q - c) / RADIUS, eta)[0]

    h = mp.mpf("1e-10")
    pu, pv = (point(h, 0) - point(-h, 0)) / (2 * h), (point(0, h) - point(0, -h)) / (2 * h)
    yu, yv = (ray(h, 0) - ray(-h, 0)) / (2 * h), (ray(0, h) - ray(0, -h)) / (2 * h)
    o = norm(p - L)
    t, cos_i = snell((p - L) / o, n, eta)
    return fresnel_t(cos_i, eta) * cos_i * norm(cross(pu, pv)) / (o * o * abs(dot(cross(yu, yv), t)))


def quad_hit(o, d, quad):
    """t > 1e-20 where the ray o + t d meets the quad (corners in order), else inf (two Moller-Trumbore triangles)."""
    q = [vec(x) for x in quad]
    best = mp.inf
    for a, b, e in ((q[0], q[1], q[2]), (q[0], q[2], q[3])):
        e1, e2 = b - a, e - a
        pv = cross(d, e2)
        det = dot(e1, pv)
        if det == 0:
            continue
        tv = o - a
        u, v = dot(tv, pv) / det, dot(d, cross(tv, e1)) / det
        t = dot(e2, cross(tv, e1)) / det
        if u >= 0 and v >= 0 and u + v <= 1 and t > 1e-20:
            best = min(best, t)
    return best


QUADS = (FLOOR, PLATE_IN, PLATE_OUT)


def blocked(a, b):
    """Whether a quad stands on the segment from a to b (not at its ends)."""
    d = b - a
    length = norm(d)
    return any(1e-20 < quad_hit(a, d / length, q) < length * (1 - mp.mpf("1e-20")) for q in QUADS)


def sphere_entry(o, d):
    """t of the ray's entry into the sphere (inf where it misses)."""
    f = o - vec(CENTRE)
    b = dot(f, d)
    disc = b * b - (dot(f, f) - RADIUS ** 2)
    return -b - mp.sqrt(disc) if disc > 0 and -b - mp.sqrt(disc) > 0 else mp.inf


def radiance(X, m, light):
    """The surface term (3,) at X (normal m facing the camera ray) inside the sphere."""
    out = [mp.mpf(0)] * 3
    for ef, s, o, t, p in paths(X, light):
        cos_s = -dot(t, m)
        if cos_s <= 0 or blocked(X, p) or blocked(p, vec(light["position"])):
            continue
        out = [out[k] + RHO / mp.pi * light["intensity"][k] * ef * cos_s * mp.exp(-KT[k] * s - KT_OUT[k] * o)
               for k in range(3)]
    return out


def pixel(light, i, j):
    """The pixel (3,) where its ray enters the sphere and first meets a quad inside, else None."""
    o, d = (vec(x) for x in oracle.camera_ray(VIEW, i, j))
    t0 = sphere_entry(o, d)
    if t0 == mp.inf or any(quad_hit(o, d, q) < t0 for q in QUADS):
        return None
    P = o + t0 * d
    n = (P - vec(CENTRE)) / RADIUS
    cos = -dot(d, n)
    if any(quad_hit(P, d + 2 * cos * n, q) < mp.inf for q in QUADS):  # the mirror reflection is lit
        return None
    w = snell(d, n, mp.mpf(ETA))[0]
    exit_t = -2 * dot(P - vec(CENTRE), w)
    hits = [(quad_hit(P, w, q), q) for q in (FLOOR, PLATE_IN)]
    ell, quad = min(hits, key=lambda h: h[0])
    if not ell < exit_t:
        return None
    q = [vec(x) for x in quad]
    m = cross(q[1] - q[0], q[2] - q[0])
    m = m / norm(m)
    m = m if dot(m, w) < 0 else -m
    lb = radiance(P + ell * w, m, light)
    scale = fresnel_t(cos, mp.mpf(ETA)) / ETA ** 2
    return [mp.exp(-KT_OUT[k] * t0) * scale * mp.exp(-KT[k] * ell) * lb[k] for k in range(3)]


def main():
    out = {"points": {}, "pixels": {}}
    for name, light in LIGHTS.items():
        out["points"][name] = [[[mp.nstr(x, 25) for x in (ef, s, o, *t)] for ef, s, o, t, _ in paths(vec(X), light)]
                               for X in POINTS]
        out["pixels"][name] = [[i, j, [mp.nstr(x, 25) for x in value]] for j in range(VIEW["height"])
                               for i in range(VIEW["width"]) if (value := pixel(light, i, j)) is not None]
    PATH.write_text(json.dumps(out, indent=1) + "\n")
    print(PATH, {k: len(v) for k, v in out["pixels"].items()},
          {k: [len(p) for p in v] for k, v in out["points"].items()})


if __name__ == "__main__":
    main()
