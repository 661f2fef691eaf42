"""A point or spot light reaches the inside of a convex refractive shape through every face it is
outside of (media/slab.py `faces_point`): a water box (ior 1.33) under a lamp above its top and a
glass block (ior 1.5) under a spot from the side, both seen through a face the light is behind.

On main before this change (624a954) every pixel of both images was exactly 0.0 (quadrature): the
light entered only through the plane of the face the camera ray entered by, and the light is behind
that plane (`test_the_light_is_behind_the_entry_face`).

The twin uses the geometry alone: for each face whose plane the light is outside of, Fermat's path
to the inside point lies in the plane of incidence (through the light and the point, normal to the
face), and its refraction point is the root of Snell's law there (scipy brentq); it counts where that
point lies on the face. The irradiance across the refracted beam is the ray tube's,
    E = I T(cos1) sin1 / (rho cos2 (hl / cos1^2 + z cos1 / (eta cos2^3))),
checked against finite differences of the refraction map (`test_ray_tube_irradiance`). The pixel is
exp(-kt_out t_cam) T_cam / eta^2 times the sum over faces of
    int ks Phi(mu) F E exp(-kt_in (x + k) - kt_out o) dx
(scipy quad, with the x where a refraction point crosses a face's edge or the spot's cone levels as
`points`, those found by bisecting the indicator between samples).
"""
import math

import numpy as np
import pytest
from scipy import integrate, optimize

from raytrace.errors import UserError
from raytrace.lights import SMOOTHSTEP
from raytrace.media.slab import GEO_COLUMNS
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import oracle
from .conftest import to_toml
from .test_bounded_media import box_entry, fresnel_t, slab, snell

LO, HI = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
FACES = [np.eye(3)[a] * s for a in range(3) for s in (-1.0, 1.0)]
CAMERA = {"position": [0.4, 0.1, 5.0], "look_at": [0.0, 0.0, 0.0], "fov": 18.0, "width": 6, "height": 5,
          "spp": 1}
# the lamp is above the top and beyond the +x side: it reaches the inside through both, and the
# refraction points cross the edge between them
WATER = {"name": "water_box", "camera": CAMERA,
         "shape": [{"primitive": "box", "min": LO.tolist(), "max": HI.tolist(),
                    "interior": {"sigma_a": [0.3, 0.1, 0.05], "sigma_s": [0.4, 0.5, 0.7],
                                 "phase": {"type": "hg", "g": 0.4}, "ior": 1.33}}],
         "light": [{"position": [1.5, 2.2, 0.3], "intensity": [5.0, 4.0, 3.0]}],
         "medium": {"sigma_a": 0.01, "sigma_s": 0.0}}
GLASS = {"name": "glass_block", "camera": CAMERA,
         "shape": [{"primitive": "box", "min": LO.tolist(), "max": HI.tolist(),
                    "interior": {"sigma_a": [0.2, 0.2, 0.1], "sigma_s": [0.6, 0.5, 0.4],
                                 "phase": {"type": "hg", "g": -0.2}, "ior": 1.5}}],
         "light": [{"type": "spot", "position": [-2.6, 1.3, 0.1], "look_at": [0.0, -0.2, 0.0], "intensity": 30.0,
                    "cone_angle": 24.0, "falloff_start": 14.0}],
         "medium": {"sigma_a": 0.0, "sigma_s": 0.0}}


def fermat(X, L, n, c, eta):
    """(R, o, k, cos1, cos2, rho, z) of Fermat's path from L (outside plane n·q = c) to X (inside)
    through that plane: Snell's law sin1 = eta sin2 in the plane of incidence, solved by brentq."""
    z, hl = c - n @ X, n @ L - c
    Xf, Lf = X + z * n, L - hl * n
    rho = float(np.linalg.norm(Lf - Xf))
    if rho < 1e-13:
        return Xf, hl, z, 1.0, 1.0, 0.0, z
    r = optimize.brentq(lambda r: (rho - r) / math.hypot(rho - r, hl) - eta * r / math.hypot(r, z), 0.0, rho,
                        xtol=1e-16, rtol=1e-15)
    o, k = math.hypot(rho - r, hl), math.hypot(r, z)
    return Xf + r * (Lf - Xf) / rho, o, k, hl / o, z / k, rho, z


def tube(hl, z, cos1, cos2, rho, eta):
    """The ray tube's irradiance per unit intensity and transmittance, off the normal."""
    sin1 = math.sqrt(1.0 - cos1 * cos1)
    return sin1 / (rho * cos2 * (hl / cos1**2 + z * cos1 / (eta * cos2**3)))


def on_face(R, n):
    """Whether R on the plane of face n of the box lies on that (closed) face, exactly: the twin is the
    exact model, against which the renderer's own face test (to 1e-12 of the scene) is an error its
    bound carries (tests/test_refracted_point_bounds.py)."""
    return all(LO[a] <= R[a] <= HI[a] for a in range(3) if n[a] == 0.0)


def spot_terms(light):
    if light.get("type") != "spot":
        return None
    axis = np.array(light["look_at"], float) - np.array(light["position"], float)
    return axis / np.linalg.norm(axis), math.cos(math.radians(light["cone_angle"])), \
        math.cos(math.radians(light["falloff_start"]))


def segment_geo(segments, light):
    """The kernels' geometry rows (N, GEO_COLUMNS) of segments [(o, d, t)] under a lamp or spot `light` (its cone
    and smoothstep falloff; a lamp's cone row never cuts)."""
    geo = np.zeros((len(segments), GEO_COLUMNS))
    for k, (o, d, _) in enumerate(segments):
        geo[k, :3], geo[k, 3:6], geo[k, 6:9] = o, d, light["position"]
    spot = spot_terms(light)
    if spot is None:
        geo[:, 9:12], geo[:, 12:14], geo[:, 17] = [0.0, 0.0, -1.0], [-2.0, -1.5], SMOOTHSTEP
    else:
        geo[:, 9:12], geo[:, 12:14], geo[:, 17] = spot[0], spot[1:], SMOOTHSTEP
    return geo


def smoothstep(c, cos_end, cos_start):
    if c >= cos_start:
        return 1.0
    if c <= cos_end:
        return 0.0
    t = (c - cos_end) / (cos_start - cos_end)
    return t * t * (3.0 - 2.0 * t)


def switches(p, w, ell, value, samples=400):
    """The x in (0, ell) where value(x) (a step or kink indicator) changes along the segment, bisected."""
    xs = np.linspace(0.0, ell, samples + 1)
    on = [value(x) for x in xs]
    out = []
    for i in np.nonzero(np.array(on[:-1]) != np.array(on[1:]))[0]:
        a, b = xs[i], xs[i + 1]
        while b - a > 4e-16 * ell:
            m = 0.5 * (a + b)
            a, b = (m, b) if value(m) == on[i] else (a, m)
        out.append(0.5 * (a + b))
    return out


def camera_entry(scene, i, j, eta):
    """(t0, entry point, refracted direction, incidence and refraction angles) of pixel (i, j)'s ray
    into the box, None where it misses."""
    o_cam, d = oracle.camera_ray(scene["camera"], i, j)
    t0, n_in = box_entry(o_cam, d, LO, HI)
    if n_in is None:
        return None
    w, ti, tt = snell(d, n_in, eta)
    return t0, o_cam + t0 * d, w, ti, tt


def twin_pixel(scene, i, j, crossings=None, emitters=None):
    """The pixel's inside single scattering (3,), from the geometry alone; `crossings` (a list) gets
    the number of points where a refraction point crosses its face's edge, per lit face. `emitters`:
    instead of the scene's light, points (position, intensity (3,), emitter normal) of Lambertian
    emitters (intensity times the cosine to their normal, continuous where it is positive)."""
    inner, light = scene["shape"][0]["interior"], scene["light"][0]
    eta, g = inner["ior"], inner["phase"]["g"]
    ks = np.array(inner["sigma_s"], float)
    kt = np.array(inner["sigma_a"], float) + ks
    kt_out = scene["medium"]["sigma_a"] + scene["medium"]["sigma_s"]
    entry = camera_entry(scene, i, j, eta)
    if entry is None:
        return np.zeros(3)
    t0, p, w, ti, tt = entry
    ell, _ = oracle.box_exit(p, w, LO, HI)
    out = np.zeros(3)
    if emitters is None:
        emitters = [(np.array(light["position"], float), np.broadcast_to(np.array(light["intensity"], float), (3,)),
                     None)]
    spot = spot_terms(light) if emitters[0][2] is None else None
    for L, inten, normal in emitters:
        out += _from_light(L, inten, normal, spot, p, w, ell, eta, g, ks, kt, kt_out, crossings)
    return math.exp(-kt_out * t0) * fresnel_t(ti, tt, eta) / eta**2 * out


def _from_light(L, inten, normal, spot, p, w, ell, eta, g, ks, kt, kt_out, crossings):
    """One light point's contribution to `twin_pixel` (before the camera ray's entry factors)."""
    out = np.zeros(3)
    for n in FACES:
        c = 1.0
        if n @ L <= c:
            continue

        def lit(x):
            R = fermat(p + x * w, L, n, c, eta)[0]
            return on_face(R, n)

        def cone(x):  # which side of each cone level the leaving direction is on
            R = fermat(p + x * w, L, n, c, eta)[0]
            u = (R - L) / np.linalg.norm(R - L)
            return (u @ spot[0] > spot[1], u @ spot[0] > spot[2])

        def f(x, ch):
            X = p + x * w
            R, o, k, cos1, cos2, rho, z = fermat(X, L, n, c, eta)
            if not on_face(R, n):
                return 0.0
            hl = n @ L - c
            e = fresnel_t(math.acos(cos1), math.asin(math.sqrt(1 - cos1**2) / eta), eta) * tube(hl, z, cos1, cos2,
                                                                                                 rho, eta)
            light_dir = (X - R) / k  # the light's direction of travel inside
            mu = float(light_dir @ -w)
            fall = 1.0
            if spot:
                fall = smoothstep(float((R - L) @ spot[0]) / o, spot[1], spot[2])
            if normal is not None:
                fall = max(0.0, float((R - L) @ normal) / o)
            return ks[ch] * oracle.phase("hg", g, mu) * fall * e * math.exp(-kt[ch] * (x + k) - kt_out * o)

        edges = switches(p, w, ell, lit)
        if crossings is not None:
            crossings.append(len(edges))
        cuts = edges + (switches(p, w, ell, cone) if spot else [])
        for ch in range(3):
            val = integrate.quad(f, 0.0, ell, args=(ch,), points=sorted(cuts) or None, epsabs=0.0, epsrel=1e-12,
                                 limit=400)[0]
            out[ch] += val * inten[ch]
    return out


def image(scene, method, params=None, seed=0):
    prep = prepare(scene_from_text(to_toml(scene), scene["name"]))
    return render(prep, method, params or {}, RenderOptions(threads=1, seed=seed))


@pytest.fixture(scope="module", params=[WATER, GLASS], ids=["water_lamp_above", "glass_spot_beside"])
def case(request):
    scene, crossings = request.param, []
    twin = np.array([[twin_pixel(scene, i, j, crossings) for i in range(CAMERA["width"])]
                     for j in range(CAMERA["height"])])
    return scene, twin, crossings


def test_ray_tube_irradiance():
    """The closed form against finite differences of the refraction map: the flux I T cos1 dA_R / o^2
    through a patch dA_R of the boundary spreads over cos2 |det J| dA_R across the beam at depth z,
    J the Jacobian of the map from the refraction point to where its refracted ray meets that depth."""
    eta, L, n = 1.33, np.array([0.4, 1.7, -0.2]), np.array([0.0, 1.0, 0.0])

    def land(R, z):  # the refracted ray from R reaches depth z below the plane y = 0
        i = (R - L) / np.linalg.norm(R - L)
        t, _, _ = snell(i, n, eta)
        return R + t * (z / -t[1])

    for X in (np.array([1.1, -0.6, 0.5]), np.array([-0.7, -1.4, 0.9]), np.array([2.5, -0.3, -1.0])):
        R, o, k, cos1, cos2, rho, z = fermat(X, L, n, 0.0, eta)
        assert np.allclose(land(R, z), X, atol=1e-12)
        h = 1e-5
        J = np.array([[(land(R + h * e, z) - land(R - h * e, z))[a] / (2 * h) for e in (np.eye(3)[0], np.eye(3)[2])]
                      for a in (0, 2)])
        fd = cos1 / (o * o * cos2 * abs(np.linalg.det(J)))
        assert abs(tube(L[1], z, cos1, cos2, rho, eta) / fd - 1.0) < 1e-8


def test_the_light_is_behind_the_entry_face(case):
    """Every pixel enters through the +z face, which the light is behind (the old model's 0), and the
    light reaches them through two faces, whose refraction points cross an edge on several segments."""
    scene, twin, crossings = case
    L = np.array(scene["light"][0]["position"])
    assert L[2] < 1.0
    lit = twin[..., 1] > 0
    assert np.count_nonzero(lit) == CAMERA["width"] * CAMERA["height"]
    assert sum(L @ n > 1.0 for n in FACES) == 2
    assert sum(crossings) >= 3, crossings


def test_quadrature_matches_the_twin(case):
    scene, twin, _ = case
    res = image(scene, "quadrature", {"rtol": 1e-11})
    rel = np.abs(res.image - twin) / twin
    assert np.max(rel) < 1e-8, np.max(rel)
    assert res.stats["inside: integrals not converged"] == 0


def test_raymarch_and_montecarlo_take_the_same_paths(case):
    """The midpoint rule converges to the twin (first order where a face's term switches on or off);
    free-path samples are unbiased with their own variance (mean squared z-score about 1)."""
    scene, twin, _ = case
    errs = [np.max(np.abs(image(scene, "raymarch", {"steps": n}).image - twin) / twin) for n in (128, 512)]
    assert errs[1] < 5e-3 and errs[1] < errs[0] / 2.5, errs
    res = image(scene, "montecarlo", {"samples": 64}, seed=5)
    z2 = np.mean((res.image - twin) ** 2 / res.variance)
    assert 0.3 < z2 < 3.5, z2


@pytest.mark.parametrize("method", ["analytic", "slab_approx"])
def test_analytic_and_slab_approx_refuse(case, method):
    """analytic has no closed form for point light inside shapes; slab_approx's separable
    approximation is for index-matched boundaries: both refuse, naming the methods that take it."""
    scene, _, _ = case
    with pytest.raises(UserError, match="quadrature, raymarch, montecarlo"):
        image(scene, method)


@pytest.mark.parametrize("spot", [False, True])
def test_only_the_entry_face_lit_is_the_entry_plane(spot):
    """A lamp (or spot) above the top of a box, a segment entering through the top: the light is
    outside that plane only, every refraction point lies on the top face, and the integrand is the
    entry plane's (`refracted_point`) bit for bit, at entry points within float32 of the plane."""
    from raytrace.media import slab
    planes = np.array([[-1, 0, 0, 1], [0, -1, 0, 1], [0, 0, -1, 1], [0, 0, 1, 1], [0, 1, 0, 1], [1, 0, 0, 1.0]])
    rng = np.random.default_rng(1)
    L, n = np.array([0.1, 2.6, -0.2]), np.array([0.0, 1.0, 0.0])
    axis = (np.array([0.3, 0.0, 0.2]) - L) / np.linalg.norm(np.array([0.3, 0.0, 0.2]) - L)
    ce, cs = (math.cos(math.radians(25)), math.cos(math.radians(15))) if spot else (-3.0, -2.0)
    for _ in range(4):
        p = np.array([rng.uniform(-1, 1), 1.0 - rng.uniform(-1e-7, 1e-7), rng.uniform(-1, 1)])
        w = np.array([rng.uniform(-0.3, 0.3), -0.9, rng.uniform(-0.3, 0.3)])
        w /= np.linalg.norm(w)
        geo = np.zeros(slab.GEO_COLUMNS)
        geo[:3], geo[3:6], geo[6:9], geo[14:17], geo[12:14] = p, w, L, n, (ce, cs)
        geo[9:12] = axis if spot else 0.0
        a, hl = -w @ n, (L - p) @ n
        lh = (L - p) - hl * n
        wl, ll = (w + a * n) @ lh, lh @ lh
        na = n @ geo[9:12]
        terms = (w @ geo[9:12] + a * na, (L - p) @ geo[9:12] - hl * na, na) if spot else (0.0, 0.0, 0.0)
        faces = np.empty((6, slab.FACE_COLUMNS))
        m = slab.refracting_faces(geo, planes, a, hl, wl, ll, (*terms, ce, cs, 0.0), faces)
        assert m == 1 and faces[0, 17] == 4
        for x in rng.uniform(0.0, 2.0, 200):
            old = slab.refracted_point(x, wl, ll, a, hl, 1.33, 0.7, 0.4, 1, 0.4, 0.01, *terms, ce, cs, 0)
            new = slab.faces_point(x, faces[:1], planes, 1.33, 0.7, 0.4, 1, 0.4, 0.01, ce, cs, 0)
            assert new == old


# the rock: a face toward the camera's side of the box and toward the light's (the lamp is beyond +x,
# the spot beyond -x)
ROCKS = {"water_box": (np.array([-0.8, -0.6, -0.8]), np.array([-0.15, 0.3, -0.1])),
         "glass_block": (np.array([0.15, -0.6, -0.8]), np.array([0.8, 0.3, -0.1]))}


def rock_pixel(scene, rock, i, j):
    """The radiance (3,) of pixel (i, j) seeing the rock inside the box (0 where it does not): the lamp
    through every face it is outside of (Fermat's path on the face, Fresnel's T, the ray tube, the
    spot's falloff on the direction it leaves in), rho / pi E cos exp(-kt k - kt_out o) at the rock,
    carried out along the camera ray."""
    inner, light = scene["shape"][0]["interior"], scene["light"][0]
    eta, rho_s = inner["ior"], scene["shape"][1]["reflectance"]
    kt = np.array(inner["sigma_a"], float)
    kt_out = scene["medium"]["sigma_a"]
    L = np.array(light["position"], float)
    spot = spot_terms(light)
    entry = camera_entry(scene, i, j, eta)
    if entry is None:
        return np.zeros(3)
    t0, p, w, ti, tt = entry
    hit = slab(p, w, *rock)
    if hit is None or hit[0] <= 0.0:
        return np.zeros(3)
    ell, _, n = hit
    X = p + ell * w
    out = np.zeros(3)
    for nf in FACES:
        if nf @ L <= 1.0:
            continue
        R, o, k, cos1, cos2, rho, z = fermat(X, L, nf, 1.0, eta)
        if not on_face(R, nf):
            continue
        e = fresnel_t(math.acos(cos1), math.asin(math.sqrt(1 - cos1**2) / eta), eta) * tube(nf @ L - 1.0, z, cos1,
                                                                                               cos2, rho, eta)
        fall = smoothstep(float((R - L) @ spot[0]) / o, spot[1], spot[2]) if spot else 1.0
        u = (R - X) / k
        out += np.array(light["intensity"], float) * e * fall * max(float(n @ u), 0.0) * np.exp(-kt * k - kt_out * o)
    return rho_s / math.pi * out * np.exp(-kt * ell - kt_out * t0) * fresnel_t(ti, tt, eta) / eta**2


@pytest.mark.parametrize("lit", [WATER, GLASS], ids=["water_lamp_above", "glass_spot_beside"])
def test_a_surface_inside_is_lit_through_every_face(lit):
    """A rock (an opaque box) inside the water box and the glass block, lit by the lamp above or the
    spot beside through the faces the light is outside of, seen through the +z face (behind the light):
    quadrature within 1e-9 of the twin (`rock_pixel`; the medium only absorbs, so that the pixel is
    the surface term alone). Until this change such a scene was refused."""
    inner = {**lit["shape"][0]["interior"], "sigma_s": 0.0}
    rock = ROCKS[lit["name"]]
    scene = {**lit, "name": "rock_" + lit["name"],
             "shape": [{**lit["shape"][0], "interior": inner},
                       {"primitive": "box", "min": rock[0].tolist(), "max": rock[1].tolist(), "reflectance": 0.6}]}
    twin = np.array([[rock_pixel(scene, rock, i, j) for i in range(CAMERA["width"])] for j in range(CAMERA["height"])])
    res = image(scene, "quadrature", {"rtol": 1e-11})
    seen = twin[..., 1] > 0.0
    assert seen.sum() >= 6, seen
    assert np.all(res.image[~seen] == 0.0)
    assert np.max(np.abs(res.image[seen] - twin[seen]) / twin[seen]) < 1e-9
