"""A point or spot light inside a refractive exact sphere (a bulb in a glass globe): the inside rows see it along
straight paths wholly inside; surfaces outside are lit by its light refracted out of the sphere
(interiors/held.py `lit_from_inside`, media/sphere_refraction.py `surface_out_of_sphere`): each refracted path
out, Fresnel's T, the ray tube's irradiance, nothing beyond the critical angle.

The twin is built from the geometry alone, in 30 digits (mpmath). The paths from the light L to a point X outside
are the stationary points of the optical path eta |P - L| + |X - P| over the sphere's points P; the normal at P
lies in the plane of the centre, L and X, so they are its stationary points over that great circle: the sign
changes of its derivative on a fine grid of angles, each refined by mpmath's findroot, kept where X lies outside
the tangent plane at P. The irradiance is the light's solid angle per unit area of the path map's image, by central
finite differences of the map from a direction leaving the light to where its ray, meeting the sphere (the
quadratic's root) and refracted out by Snell's law in vector form, meets the plane through X. A pixel is the
camera ray's path: straight to the floor; or into the globe (Fresnel's T / eta^2 for what comes out of it, the
mirror's 1 - T for what the reflected ray sees), the inside single scattering (scipy quad, straight paths from
the light), and out through the far side (T eta^2 exp(-sigma_t ell) for what it sees beyond, nothing on total
internal reflection)."""
import math

import mpmath as mp
import numpy as np
import pytest

from raytrace.lights import NO_CONE, SMOOTHSTEP
from raytrace.media.sphere_refraction import MAX_PATHS, surface_out_of_sphere

from . import oracle
from .test_bounded_media import fresnel_t
from .test_lamp_in_glass import CAMERA, ETA, KA, KA_OUT, KS, LAMP, SPOT, dot, inside, refract, \
    floor_radiance as box_floor, inner_and_beside, refract_mp, refused, scene as box_scene, tube_area, unit
from .test_light_inside import image, raymarch_and_montecarlo
from .test_refracted_point_light import smoothstep, spot_terms

CENTRE, RADIUS = np.array([0.0, 0.0, 0.0]), 1.2
SPHERE = np.array([*CENTRE, RADIUS])
NEAR = {"position": [0.75, 0.3, 0.5], "intensity": [5.0, 4.0, 3.0]}  # 0.95 from the centre: paths totally reflected
GRID = 4000  # angles of the great circle on which the optical path's stationary points are bracketed


def scene(light, medium=None):
    sc = box_scene(light, medium)
    sc["name"] = "globe"
    sc["shape"][0] = {"primitive": "sphere", "center": CENTRE.tolist(), "radius": RADIUS, "exact": True,
                      "interior": sc["shape"][0]["interior"]}
    return sc


def circle(L, X):
    """(e1, e2): the orthonormal frame of the great circle in the plane of the centre, L and X (e1 toward X)."""
    e1 = (X - CENTRE) / np.linalg.norm(X - CENTRE)
    e2 = (L - CENTRE) - ((L - CENTRE) @ e1) * e1
    if np.linalg.norm(e2) < 1e-9:
        e2 = np.cross(e1, [0.3, 0.5, 0.8])
    return e1, e2 / np.linalg.norm(e2)


def exit_points(L, X):
    """The refraction points (mpmath, 30 digits) of the paths from L inside to X outside: the stationary points
    of eta |P - L| + |X - P| over the great circle through the centre, L and X (bracketed on GRID angles,
    findroot), where X lies outside P's tangent plane."""
    e1, e2 = circle(L, X)
    th = np.linspace(-math.pi, math.pi, GRID + 1)
    P = CENTRE + RADIUS * (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2)
    dP = RADIUS * (-np.sin(th)[:, None] * e1 + np.cos(th)[:, None] * e2)
    u, v = P - L, X - P
    slope = ETA * np.einsum("ij,ij->i", u, dP) / np.linalg.norm(u, axis=1) - np.einsum("ij,ij->i", v, dP) / \
        np.linalg.norm(v, axis=1)
    out = []
    with mp.workdps(30):
        Lm, Xm = [mp.mpf(float(x)) for x in L], [mp.mpf(float(x)) for x in X]
        E1, E2 = [mp.mpf(float(x)) for x in e1], [mp.mpf(float(x)) for x in e2]

        def point(t):
            return [CENTRE[k] + RADIUS * (mp.cos(t) * E1[k] + mp.sin(t) * E2[k]) for k in range(3)]

        def derivative(t):
            Pm = point(t)
            dPm = [RADIUS * (-mp.sin(t) * E1[k] + mp.cos(t) * E2[k]) for k in range(3)]
            return ETA * dot(unit([p - q for p, q in zip(Pm, Lm)]), dPm) - dot(unit([x - p for x, p in zip(Xm, Pm)]),
                                                                               dPm)

        for j in np.nonzero(np.sign(slope[:-1]) != np.sign(slope[1:]))[0]:
            t = mp.findroot(derivative, (mp.mpf(th[j]), mp.mpf(th[j + 1])), solver="anderson")
            Pm = point(t)
            if dot([x - p for x, p in zip(Xm, Pm)], [p - CENTRE[k] for k, p in enumerate(Pm)]) > 0:
                out.append(Pm)
    return out


def hit_sphere(L, u):
    """Where the ray from L inside the sphere along the unit u meets it (mpmath lists)."""
    f = [l - c for l, c in zip(L, CENTRE)]
    b = dot(f, u)
    t = -b + mp.sqrt(b * b - dot(f, f) + RADIUS * RADIUS)
    return [l + t * x for l, x in zip(L, u)]


def irradiance(light, X, normal=None):
    """The light's irradiance (3,) at X outside the sphere, per unit area of the plane through X of unit `normal`
    (None: across each ray), summed over its paths out (`paths_out`), attenuated."""
    return sum((e for e, _, _ in paths_out(light, X, normal)), np.zeros(3))


def paths_out(light, X, normal=None):
    """Per path out of the sphere to X: (e, toward, cond), e the light's irradiance (3,) at X per unit area of the
    plane through X of unit `normal` (None: across the ray), attenuated, toward the unit direction from X to the
    refraction point, and cond e's relative change per unit relative change of the light's coordinates (first
    order: e falls with the outside cosine squared toward the critical angle, 2 eta^2 cos_in / (s cos_out^2) |L|
    per unit, s the path inside; the data's own rounding, whatever computes e): the light's solid angle per unit
    area of the path map's image, central differences in 30 digits (step 1e-12: truncation 1e-24, rounding
    1e-18)."""
    L = np.array(light["position"], float)
    inten = np.array(light["intensity"], float)
    spot, kt = spot_terms(light), KS + KA
    out = []
    for R in exit_points(L, X):
        with mp.workdps(30):
            Lm, Xm = [mp.mpf(float(v)) for v in L], [mp.mpf(float(v)) for v in X]
            u0 = unit([r - l for r, l in zip(R, Lm)])
            n0 = [(r - c) / RADIUS for r, c in zip(R, CENTRE)]
            v0 = refract_mp(u0, [-v for v in n0], 1 / mp.mpf(ETA))
            nrm = v0 if normal is None else [mp.mpf(float(v)) for v in normal]
            e1 = unit([u0[1] * 0.8 - u0[2] * 0.5, u0[2] * 0.3 - u0[0] * 0.8, u0[0] * 0.5 - u0[1] * 0.3])
            e2 = [u0[1] * e1[2] - u0[2] * e1[1], u0[2] * e1[0] - u0[0] * e1[2], u0[0] * e1[1] - u0[1] * e1[0]]

            def end(s, t):
                u = unit([x + s * y + t * z for x, y, z in zip(u0, e1, e2)])
                P = hit_sphere(Lm, u)
                v = refract_mp(u, [-(p - c) / RADIUS for p, c in zip(P, CENTRE)], 1 / mp.mpf(ETA))
                step = dot([x - y for x, y in zip(Xm, P)], nrm) / dot(v, nrm)
                return [pv + step * vv for pv, vv in zip(P, v)]

            area = tube_area(end, nrm)
            cos_out, cos_in = float(dot(v0, n0)), float(dot(u0, n0))
            Rf, u0f = np.array([float(v) for v in R]), np.array([float(v) for v in u0])
        fall = 1.0 if spot is None else smoothstep(float(u0f @ spot[0]), spot[1], spot[2])
        att = np.exp(-kt * np.linalg.norm(Rf - L) - KA_OUT * np.linalg.norm(X - Rf))
        e = fresnel_t(math.acos(cos_out), math.acos(cos_in), ETA) * fall * inten * att / area
        s = float(np.linalg.norm(Rf - L))
        out.append((e, (Rf - X) / np.linalg.norm(Rf - X), 2.0 * ETA**2 * cos_in * np.linalg.norm(L) / (s * cos_out**2)))
    return out


def kernel(light, q):
    """`surface_out_of_sphere` at the points q (M, 3) for a unit light: (value, toward, inside, outside)."""
    spot = spot_terms(light) or (np.array([0.0, 0.0, -1.0]), *NO_CONE)
    m = len(q)
    out = np.zeros((m, MAX_PATHS)), np.zeros((m, MAX_PATHS, 3)), np.zeros((m, MAX_PATHS)), np.zeros((m, MAX_PATHS))
    surface_out_of_sphere(np.ascontiguousarray(q), SPHERE, np.array(light["position"], float), spot[0],
                          np.array([spot[1], spot[2], SMOOTHSTEP]), ETA, *out)
    return out


def test_the_kernel_against_the_twin():
    """`surface_out_of_sphere` at 300 points around the globe (the irradiance across the ray summed over the paths,
    each path's direction toward its refraction point, the spot's falloff, the legs' lengths through the
    attenuation) within 1e-12 of the twin's (measured 2.0e-14), but for the light's rounding carried through
    (`paths_out`'s cond x 8 ulp: a path within 2.5e-5 of the critical angle in cosine measured 1.2e-12, its
    allowance 5.4e-11); a light near the glass, where paths beyond the critical angle are totally reflected
    (points with no path) and two reach some points (a caustic outside)."""
    rng = np.random.default_rng(7)
    q = rng.normal(size=(300, 3))
    q *= (rng.uniform(RADIUS * 1.001, 4.0, len(q)) / np.linalg.norm(q, axis=1))[:, None]
    counts, worst = [], 0.0
    for light in (LAMP, SPOT, NEAR):
        value, toward, ins, outs = kernel(light, q)
        unit_light = dict(light, intensity=[1.0, 1.0, 1.0])
        for i, X in enumerate(q):
            counts.append(np.count_nonzero(value[i] > 0.0))
            e = value[i] * np.exp(-(KS[0] + KA[0]) * ins[i] - KA_OUT * outs[i])
            ref = paths_out(unit_light, X)
            total = sum(r[0][0] for r in ref)
            tol = 1e-12 * total + sum(r[0][0] * r[2] for r in ref) * 8.0 * np.finfo(float).eps
            assert sum(r[0][0] > 0.0 for r in ref) == counts[-1], (i, len(ref), counts[-1])
            assert abs(float(e.sum()) - total) <= tol, (i, e.sum(), total, tol)
            assert np.all(np.abs(e @ toward[i] - sum(r[0][0] * r[1] for r in ref)) <= tol), i
            worst = max(worst, abs(float(e.sum()) - total) / tol if tol > 0.0 else 0.0)
    counts = np.bincount(counts)
    assert counts[0] > 20 and counts[2] > 5, counts  # none (total reflection), two (beside the caustic)


def sphere_hits(o, d):
    """The roots t0 <= t1 of |o + t d - c| = R (unit d), or None."""
    f = o - CENTRE
    b = float(f @ d)
    disc = b * b - float(f @ f) + RADIUS**2
    if disc <= 0.0:
        return None
    return -b - math.sqrt(disc), -b + math.sqrt(disc)


def floor_radiance(light, o, d):
    """What the ray from o along d (outside the globe) sees of the floor lit through the globe, 0 where it misses,
    with the outside medium's transmittance."""
    return box_floor(light, o, d, lit_by=irradiance)


def twin(light):
    img = np.zeros((CAMERA["height"], CAMERA["width"], 3))
    for j in range(CAMERA["height"]):
        for i in range(CAMERA["width"]):
            o, d = oracle.camera_ray(CAMERA, i, j)
            hits = sphere_hits(o, d)
            if hits is None or hits[0] <= 0.0:
                img[j, i] = floor_radiance(light, o, d)
                continue
            p = o + hits[0] * d
            n_in = (p - CENTRE) / RADIUS
            cos_i = -float(d @ n_in)
            w = refract(d, n_in, ETA)
            t_in = fresnel_t(math.acos(cos_i), math.acos(-float(w @ n_in)), ETA)
            mirrored = floor_radiance(light, p, d + 2.0 * cos_i * n_in)
            ell = sphere_hits(p, w)[1]
            seen = inside(light, p, w, ell)
            m = -(p + ell * w - CENTRE) / RADIUS  # the exit's inward normal
            out = refract(w, m, 1.0 / ETA)
            if out is not None:
                t_out = fresnel_t(math.acos(abs(float(w @ m))), math.acos(abs(float(out @ m))), 1.0 / ETA)
                seen += np.exp(-(KS + KA) * ell) * t_out * ETA**2 * floor_radiance(light, p + ell * w, out)
            img[j, i] = math.exp(-KA_OUT * hits[0]) * ((1.0 - t_in) * mirrored + t_in / ETA**2 * seen)
    return img


@pytest.fixture(scope="module", params=["lamp", "spot", "near"])
def case(request):
    light = {"lamp": LAMP, "spot": SPOT, "near": NEAR}[request.param]
    return light, twin(light)


def test_quadrature_from_a_lamp_in_a_globe(case):
    """quadrature (rtol 1e-10, volumetric shadows) within 1e-9 of the twin on every pixel, inside its bound, every
    bound finite: the globe's fog around the light seen through the glass, the floor lit through it seen
    straight, in the globe's mirror and through it (measured 5.9e-15 lamp, 2.1e-14 spot)."""
    light, ref = case
    res = image(scene(light), "quadrature", {"rtol": 1e-10})
    err = np.abs(res.image - ref)
    assert np.count_nonzero(ref[..., 1] > 0.0) >= {id(LAMP): 30, id(SPOT): 10, id(NEAR): 20}[id(light)]  # 34, 11, 21
    assert np.all(err <= 1e-9 * ref), np.max(err / np.maximum(ref, 1e-300))
    assert np.all(np.isfinite(res.error_bound))
    assert np.all(err <= res.error_bound), np.max(err - res.error_bound)


def test_unshadowed_is_the_same(case):
    """Without volumetric shadows (nothing but the glass could shadow: the same paths) within 1e-9 too."""
    light, ref = case
    res = image(scene(light), "quadrature", {"rtol": 1e-10}, shadows=False)
    assert np.all(np.abs(res.image - ref) <= 1e-9 * ref)


def test_raymarch_and_montecarlo_from_a_lamp_in_a_globe(case):
    """Raymarch at its order, Monte Carlo unbiased over four seeds of 256 samples (test_light_inside's
    `raymarch_and_montecarlo`)."""
    light, ref = case
    raymarch_and_montecarlo(lambda method, params, seed: image(scene(light), method, params, seed=seed), ref,
                            samples=256, seeds=(3, 4, 5, 6))


def test_what_is_not_implemented_is_refused():
    """Fog outside lit from beyond radius / ior (tests/test_globe_fog.py takes it nearer), the camera inside the
    globe, a shape inside it, one reaching into it from outside (its first corner outside: not refused before, and
    unlit inside), another medium beside it, and the methods without exact paths: refused in one line,
    naming what to change."""
    inside_camera = scene(LAMP)
    inside_camera["camera"] = dict(CAMERA, position=[0.0, -0.5, 0.5])
    inner, beside = inner_and_beside(scene)
    through = scene(LAMP)  # a rod through the globe, every corner outside it
    through["shape"].append({"primitive": "box", "min": (CENTRE - [5.0, 0.05, 0.05]).tolist(),
                             "max": (CENTRE + [5.0, 0.05, 0.05]).tolist()})
    refused([(scene(NEAR, {"sigma_a": 0.02, "sigma_s": 0.05}), "quadrature", "does not scatter"),
             (inside_camera, "quadrature", "camera"),
             (inner, "quadrature", r"another shape inside it or reaching into it \(shape\[2\]\)"),
             (through, "quadrature", r"another shape inside it or reaching into it \(shape\[2\]\)"),
             (beside, "quadrature", r"another shape holding a medium \(shape\[2\]\)"),
             (scene(LAMP), "analytic", "no closed form"),
             (scene(LAMP), "slab_approx", "--method quadrature, raymarch, montecarlo")])
