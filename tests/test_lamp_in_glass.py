"""A point or spot light inside a convex refractive shape (a lamp in a glass lantern): the inside rows see
it along straight paths wholly inside; surfaces outside are lit by its light refracted out through each
face (interiors/held.py `lit_from_inside`, media/slab.py `surface_out_of_faces`): Fermat's path
reversed, Fresnel's T, the ray tube's irradiance.

The twin is built from the geometry alone, in 30 digits (mpmath). Its refraction point through a face makes
the optical path eta |R - L| + |X - R| stationary over the face's plane (Newton's method on the path's in-plane
gradient from the straight line's crossing), counted where it lies on the (closed) face; the irradiance is the
light's solid angle per unit area of the path map's image, by central finite differences of the map from a
direction leaving the light to where its ray, refracted out by Snell's law in vector form, meets the
receiving plane. A pixel is the camera ray's path: straight to the floor; or into the glass (Fresnel's T /
eta^2 for what comes out of it, the mirror's 1 - T for what the reflected ray sees), the inside single
scattering (scipy quad), and out through the far face (T eta^2 exp(-sigma_t ell) for what it sees beyond,
nothing on total internal reflection)."""
import math

import mpmath as mp
import numpy as np
import pytest
from scipy import integrate

from raytrace.errors import UserError
from raytrace.lights import NO_CONE, SMOOTHSTEP
from raytrace.media.slab import surface_out_of_faces

from . import oracle
from .test_bounded_media import box_entry, fresnel_t
from .test_light_inside import image, raymarch_and_montecarlo
from .test_refracted_point_light import smoothstep, spot_terms, switches

LO, HI = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
FACES = [np.eye(3)[a] * s for a in range(3) for s in (-1.0, 1.0)]
ETA, G = 1.5, 0.3
KS, KA = np.array([0.4, 0.5, 0.7]), np.array([0.3, 0.1, 0.05])
KA_OUT, FLOOR_Y, RHO = 0.03, -1.6, 0.5
CAMERA = {"position": [1.2, 2.4, 4.5], "look_at": [0.0, -0.9, 0.0], "fov": 55.0, "width": 8, "height": 6, "spp": 1}
LAMP = {"position": [0.3, 0.2, -0.2], "intensity": [5.0, 4.0, 3.0]}
SPOT = {"type": "spot", "position": [0.2, 0.4, 0.1], "look_at": [0.6, -1.5, 0.9], "intensity": [5.0, 4.0, 3.0],
        "cone_angle": 40.0, "falloff_start": 25.0}


def scene(light, medium=None, ior=ETA):
    return {"name": "lantern", "camera": CAMERA, "medium": medium or {"sigma_a": KA_OUT, "sigma_s": 0.0},
            "shape": [{"primitive": "box", "min": LO.tolist(), "max": HI.tolist(),
                       "interior": {"sigma_a": KA.tolist(), "sigma_s": KS.tolist(), "phase": {"type": "hg", "g": G},
                                    "ior": ior}},
                      {"primitive": "quad", "corners": [[-5.0, FLOOR_Y, 5.0], [5.0, FLOOR_Y, 5.0], [5.0, FLOOR_Y, -5.0],
                                                        [-5.0, FLOOR_Y, -5.0]], "reflectance": RHO}],
            "light": [light]}


def refract(d, n, eta):
    """d (unit) through a boundary with unit normal n facing it into relative index eta; None on total
    internal reflection."""
    c = -float(d @ n)
    k = 1.0 - (1.0 - c * c) / (eta * eta)
    if k < 0.0:
        return None
    return d / eta + (c / eta - math.sqrt(k)) * n


def on_face(R, n):
    return all(LO[a] <= R[a] <= HI[a] for a in range(3) if n[a] == 0.0)


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def tube_area(end, nrm):
    """The ray tube's cross-section on the receiving plane of normal nrm per unit square of the light's directions:
    |(d end/ds x d end/dt) . nrm| by central differences (h = 1e-12, in mpmath) of the map end(s, t) from the
    directions about the path's to the plane."""
    h = mp.mpf(10) ** -12
    js = [(x - y) / (2 * h) for x, y in zip(end(h, 0), end(-h, 0))]
    jt = [(x - y) / (2 * h) for x, y in zip(end(0, h), end(0, -h))]
    cross = [js[1] * jt[2] - js[2] * jt[1], js[2] * jt[0] - js[0] * jt[2], js[0] * jt[1] - js[1] * jt[0]]
    return float(abs(dot(cross, nrm)))


def unit(a):
    n = mp.sqrt(dot(a, a))
    return [x / n for x in a]


def exit_point(L, X, n):
    """Fermat's refraction point (mpmath, 30 digits) of the path from L inside to X outside through the plane
    of the face of outward normal n: the optical path P(R) = eta |R - L| + |X - R|, convex in R, is stationary
    where its gradient along the plane's axes a, b vanishes, eta u + w (u, w the unit vectors from L and from X
    to R); Newton's method with its Hessian eta (I - u u^T) / |R - L| + (I - w w^T) / |R - X| on the plane,
    from where the straight line LX crosses it, a step halved while it does not lower P (down to 1e-10, then
    quadratic convergence), to a step of 1e-25."""
    a, b = [e for e in np.eye(3) if e @ n == 0.0]
    with mp.workdps(30):
        Lm, Xm = [mp.mpf(float(v)) for v in L], [mp.mpf(float(v)) for v in X]
        nm, am, bm = ([mp.mpf(float(v)) for v in e] for e in (n, a, b))
        t = (float(max(n @ LO, n @ HI)) - dot(nm, Lm)) / dot(nm, [x - y for x, y in zip(Xm, Lm)])

        def legs(R):
            d1, d2 = [r - v for r, v in zip(R, Lm)], [r - v for r, v in zip(R, Xm)]
            k1, k2 = mp.sqrt(dot(d1, d1)), mp.sqrt(dot(d2, d2))
            return R, [v / k1 for v in d1], [v / k2 for v in d2], k1, k2

        R, u, w, k1, k2 = legs([y + t * (x - y) for x, y in zip(Xm, Lm)])
        for _ in range(100):
            ua, ub, wa, wb = dot(u, am), dot(u, bm), dot(w, am), dot(w, bm)
            ga, gb = ETA * ua + wa, ETA * ub + wb
            haa, hbb = ETA * (1 - ua * ua) / k1 + (1 - wa * wa) / k2, ETA * (1 - ub * ub) / k1 + (1 - wb * wb) / k2
            hab = -ETA * ua * ub / k1 - wa * wb / k2
            det = haa * hbb - hab * hab
            sa, sb = -(hbb * ga - hab * gb) / det, -(haa * gb - hab * ga) / det
            size = mp.sqrt(sa * sa + sb * sb)
            while True:
                step = legs([r + sa * x + sb * y for r, x, y in zip(R, am, bm)])
                if ETA * step[3] + step[4] < ETA * k1 + k2 or size < 1e-10:
                    break
                sa, sb, size = sa / 2, sb / 2, size / 2
            R, u, w, k1, k2 = step
            if size < 1e-25:
                return R
        raise ArithmeticError("Newton's method did not converge")


def refract_mp(d, n, eta):
    """`refract` in mpmath (lists)."""
    c = -dot(d, n)
    k = 1 - (1 - c * c) / (eta * eta)
    return [x / eta + (c / eta - mp.sqrt(k)) * m_ for x, m_ in zip(d, n)]


def irradiance(light, X, normal=None):
    """The light's irradiance (3,) at X outside the box, per unit area of the plane through X of unit
    `normal` (None: across the ray), summed over the faces whose plane X is outside of, attenuated: the
    light's solid angle per unit area of the path map's image, central differences in 30 digits (step
    1e-12: truncation 1e-24, rounding 1e-18)."""
    L = np.array(light["position"], float)
    inten = np.array(light["intensity"], float)
    spot, kt = spot_terms(light), KS + KA
    total = np.zeros(3)
    for n in FACES:
        c = float(max(n @ LO, n @ HI))
        if n @ X <= c:
            continue
        with mp.workdps(30):
            R = exit_point(L, X, n)
            Rf = np.array([float(v) for v in R])
            if not on_face(Rf, n):
                continue
            Lm, nm = [mp.mpf(float(v)) for v in L], [float(v) for v in n]
            u0 = unit([r - l for r, l in zip(R, Lm)])
            v0 = refract_mp(u0, [-v for v in nm], 1 / mp.mpf(ETA))
            nrm = v0 if normal is None else [mp.mpf(float(v)) for v in normal]
            Xm = [mp.mpf(float(v)) for v in X]
            side = [float(v) for v in (n if abs(float(dot(u0, nm))) < 0.9 else np.array([0.3, 0.5, 0.8]))]
            e1 = unit([u0[1] * side[2] - u0[2] * side[1], u0[2] * side[0] - u0[0] * side[2],
                       u0[0] * side[1] - u0[1] * side[0]])
            e2 = [u0[1] * e1[2] - u0[2] * e1[1], u0[2] * e1[0] - u0[0] * e1[2], u0[0] * e1[1] - u0[1] * e1[0]]

            def end(s, t):
                u = unit([x + s * y + t * z for x, y, z in zip(u0, e1, e2)])
                P = [lv + (c - dot(nm, Lm)) / dot(u, nm) * uv for lv, uv in zip(Lm, u)]
                v = refract_mp(u, [-x for x in nm], 1 / mp.mpf(ETA))
                step = dot([x - y for x, y in zip(Xm, P)], nrm) / dot(v, nrm)
                return [pv + step * vv for pv, vv in zip(P, v)]

            area = tube_area(end, nrm)
            cos_out, cos_in = float(abs(dot(v0, nm))), float(abs(dot(u0, nm)))
            u0f = np.array([float(v) for v in u0])
        fall = 1.0 if spot is None else smoothstep(float(u0f @ spot[0]), spot[1], spot[2])
        att = np.exp(-kt * np.linalg.norm(Rf - L) - KA_OUT * np.linalg.norm(X - Rf))
        total += fresnel_t(math.acos(cos_out), math.acos(cos_in), ETA) * fall * inten * att / area
    return total


def floor_radiance(light, o, d, lit_by=None):
    """(what the ray from o along d sees of the floor, lit from inside the box, or by `lit_by(light, point,
    normal)`, 0 where it misses), with the outside medium's transmittance."""
    if d[1] >= 0.0:
        return np.zeros(3)
    t = (FLOOR_Y - o[1]) / d[1]
    F = o + t * d
    if max(abs(F[0]), abs(F[2])) > 5.0:
        return np.zeros(3)
    return RHO / math.pi * (lit_by or irradiance)(light, F, np.array([0.0, 1.0, 0.0])) * math.exp(-KA_OUT * t)


def inside(light, p, w, ell):
    """The inside single scattering (3,) along p + x w, x in [0, ell], lit straight from inside."""
    L, inten = np.array(light["position"], float), np.array(light["intensity"], float)
    spot, kt = spot_terms(light), KS + KA

    def f(x, ch):
        X = p + x * w
        rel = X - L
        r = float(np.linalg.norm(rel))
        fall = 1.0 if spot is None else smoothstep(float(rel @ spot[0]) / r, spot[1], spot[2])
        return KS[ch] * oracle.phase("hg", G, float(-(rel @ w)) / r) * fall * inten[ch] / r**2 * math.exp(
            -kt[ch] * (x + r))

    cuts = [float((L - p) @ w)]
    if spot:
        cuts += switches(p, w, ell, lambda x: tuple(float((p + x * w - L) @ spot[0]) / np.linalg.norm(p + x * w - L)
                                                    > s for s in spot[1:]))
    cuts = sorted(x for x in cuts if 0.0 < x < ell)
    return np.array([integrate.quad(f, 0.0, ell, args=(ch,), points=cuts or None, epsabs=0.0, epsrel=1e-12,
                                    limit=400)[0] for ch in range(3)])


def twin(light):
    img = np.zeros((CAMERA["height"], CAMERA["width"], 3))
    for j in range(CAMERA["height"]):
        for i in range(CAMERA["width"]):
            o, d = oracle.camera_ray(CAMERA, i, j)
            t0, n_in = box_entry(o, d, LO, HI)
            if n_in is None:
                img[j, i] = floor_radiance(light, o, d)
                continue
            p = o + t0 * d
            cos_i = -float(d @ n_in)
            w = refract(d, n_in, ETA)
            t_in = fresnel_t(math.acos(cos_i), math.acos(-float(w @ n_in)), ETA)
            mirrored = floor_radiance(light, p, d + 2.0 * cos_i * n_in)
            ell, m = oracle.box_exit(p, w, LO, HI)  # m: the exit face's inward normal
            seen = inside(light, p, w, ell)
            out = refract(w, np.array(m, float), 1.0 / ETA)
            if out is not None:
                t_out = fresnel_t(math.acos(abs(float(w @ m))), math.acos(abs(float(out @ m))), 1.0 / ETA)
                seen += np.exp(-(KS + KA) * ell) * t_out * ETA**2 * floor_radiance(light, p + ell * w, out)
            img[j, i] = math.exp(-KA_OUT * t0) * ((1.0 - t_in) * mirrored + t_in / ETA**2 * seen)
    return img


@pytest.fixture(scope="module", params=["lamp", "spot"])
def case(request):
    light = LAMP if request.param == "lamp" else SPOT
    return light, twin(light)


def test_the_kernel_against_the_twin():
    """`surface_out_of_faces` at 300 points around the box (the irradiance across the ray, the spot's
    falloff, the legs' lengths) within 1e-12 of the twin's (measured 1.7e-14) summed over the faces, the
    refraction points' edges crossed (several faces light one point) and total internal reflection near."""
    rng = np.random.default_rng(5)
    q = rng.uniform(-3.0, 3.0, (300, 3))
    q = q[np.max(np.abs(q), axis=1) > 1.05]
    planes = np.array([[*n, 1.0] for n in FACES])
    several = 0
    for light in (LAMP, SPOT):
        spot = spot_terms(light) or (np.array([0.0, 0.0, -1.0]), *NO_CONE)
        cone = np.array([spot[1], spot[2], SMOOTHSTEP])
        value, toward = np.zeros((len(q), 6)), np.zeros((len(q), 6, 3))
        ins, outs = np.zeros((len(q), 6)), np.zeros((len(q), 6))
        surface_out_of_faces(q, planes, np.array(light["position"], float), spot[0], cone, ETA, value, toward, ins,
                             outs)
        unit = dict(light, intensity=[1.0, 1.0, 1.0])
        for i, X in enumerate(q):
            lit = value[i] > 0.0
            several += np.count_nonzero(lit) > 1
            att = np.exp(-(KS[0] + KA[0]) * ins[i] - KA_OUT * outs[i])
            ref = irradiance(unit, X)[0]
            assert abs(float(value[i] @ att) - ref) <= 1e-12 * ref, (i, value[i] @ att, ref)
    assert several > 20, several


def test_quadrature_from_a_lamp_in_glass(case):
    """quadrature (rtol 1e-10, volumetric shadows) within 1e-9 of the twin on every pixel, inside its bound where
    that is finite: the glass's fog around the light seen through a face, the floor lit through the faces seen
    straight, in the glass's mirror and through it."""
    light, ref = case
    res = image(scene(light), "quadrature", {"rtol": 1e-10})
    err = np.abs(res.image - ref)
    assert np.count_nonzero(ref[..., 1] > 0.0) >= 12  # the spot's: 14 of 48
    assert np.all(err <= 1e-9 * ref), np.max(err / np.maximum(ref, 1e-300))  # measured 4.3e-15 lamp, 3.0e-14 spot
    finite = np.isfinite(res.error_bound)
    assert np.all(err[finite] <= res.error_bound[finite]), np.max((err - res.error_bound)[finite])


def test_unshadowed_is_the_same(case):
    """Without volumetric shadows (nothing but the glass could shadow: the same paths) within 1e-9 too."""
    light, ref = case
    res = image(scene(light), "quadrature", {"rtol": 1e-10}, shadows=False)
    assert np.all(np.abs(res.image - ref) <= 1e-9 * ref)


def test_raymarch_and_montecarlo_from_a_lamp_in_glass(case):
    """Raymarch at its order, Monte Carlo unbiased over four seeds of 256 samples (test_light_inside's
    `raymarch_and_montecarlo`); the spot lights 12 pixels, its samples mostly off the cone: a heavy tail."""
    light, ref = case
    raymarch_and_montecarlo(lambda method, params, seed: image(scene(light), method, params, seed=seed), ref,
                            samples=256, seeds=(3, 4, 5, 6))


def test_what_is_not_implemented_is_refused():
    """A shape inside the lantern, another medium beside it (lit by its light refracted out), and the methods
    without exact paths: refused in one line, naming what to change (an exact sphere: tests/test_lamp_in_globe.py;
    fog outside with volumetric shadows and a floor is rendered: tests/test_lamp_in_glass_shadows.py)."""
    inner, beside = inner_and_beside(scene)
    refused([(inner, "quadrature", r"another shape inside it or reaching into it \(shape\[2\]\)"),
             (beside, "quadrature", r"another shape holding a medium \(shape\[2\]\)"),
             (scene(LAMP), "analytic", "no closed form"),
             (scene(LAMP), "slab_approx", "--method quadrature, raymarch, montecarlo")])


def inner_and_beside(scene):
    """The lamp's scene made by `scene` with a box inside its shape, and with a box of another medium beside it."""
    inner = scene(LAMP)
    inner["shape"].append({"primitive": "box", "min": [-0.5, -0.9, -0.5], "max": [-0.2, -0.6, -0.2]})
    beside = scene(LAMP)
    beside["shape"].append({"primitive": "box", "min": [2.0, -1.0, -0.5], "max": [3.0, 0.0, 0.5],
                            "interior": {"sigma_a": 0.1, "sigma_s": 0.2}})
    return inner, beside


def refused(cases):
    """Each (scene, method, words) refused in one line matching words."""
    for sc, method, words in cases:
        with pytest.raises(UserError, match=words) as err:
            image(sc, method, {})
        assert "\n" not in str(err.value)
