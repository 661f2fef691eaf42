"""Media inside shapes (raytrace/interiors/crossing.py, seed 002) against an independent per-pixel twin.

The twin re-derives everything from SCENE_FORMAT.md and the seed: the camera ray (tests/oracle.py),
its entry into an axis-aligned box by the slab test, refraction by Snell's law in angles, the
Fresnel transmittance in its angle form, the radiance factor T / eta^2 across the boundary, the
exit and, for every point of the inside segment, the light's path back to the actual box (the
entry face must be where it leaves: then the seed's planar boundary is exact), and the single
scattering integral by scipy `quad`. The renderer's `quadrature` and `analytic` (eq. 5) must agree
to 1e-9; `slab_approx` must equal the seed's approximation evaluated by the twin.
"""
import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.cli import main
from raytrace.errors import UserError
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import oracle
from .conftest import to_toml

LO, HI = np.array([-50.0, -5.0, -50.0]), np.array([50.0, 0.0, 50.0])


def box_entry(o, d, LO=LO, HI=HI):
    """(t, outward normal) where the ray from outside enters the box [LO, HI], or (inf, None)."""
    t0, t1, axis, sign = -math.inf, math.inf, -1, 0.0
    for a in range(3):
        if d[a] == 0.0:
            if not LO[a] <= o[a] <= HI[a]:
                return math.inf, None
            continue
        ta, tb = (LO[a] - o[a]) / d[a], (HI[a] - o[a]) / d[a]
        near, s = (ta, -1.0) if ta < tb else (tb, 1.0)
        if near > t0:
            t0, axis, sign = near, a, s
        t1 = min(t1, max(ta, tb))
    if t0 > t1 or t0 <= 0.0:
        return math.inf, None
    n = np.zeros(3)
    n[axis] = sign
    return t0, n


def snell(d, n, eta):
    """d refracted through the face with outward normal n (d . n < 0) by angles: (t, theta_i, theta_t)."""
    ti = math.acos(-float(d @ n))
    tt = math.asin(math.sin(ti) / eta)
    tangent = d - float(d @ n) * n
    tn = np.linalg.norm(tangent)
    tangent = tangent / tn if tn > 0 else np.zeros(3)
    return math.sin(tt) * tangent - math.cos(tt) * n, ti, tt


def fresnel_t(ti, tt, eta):
    if eta == 1.0:
        return 1.0
    if ti == 0.0:
        return 1.0 - ((eta - 1) / (eta + 1)) ** 2
    rs = math.sin(ti - tt) / math.sin(ti + tt)
    rp = math.tan(ti - tt) / math.tan(ti + tt)
    return 1.0 - 0.5 * (rs * rs + rp * rp)


def back_to_boundary(x, direction, n_entry, lo=LO, hi=HI, strict=True):
    """Distance from x inside the box along `direction` to the boundary; with `strict` the face must
    be the entry face (where the seed's planar boundary is exact)."""
    t, inward = oracle.box_exit(x, direction, lo, hi)
    assert not strict or np.allclose(-inward, n_entry), "the light leaves through another face: fix the geometry"
    return t


def plane_hit(origin, direction, n):
    """Where the ray meets the entry plane y = HI[1] (the box's top, normal n = +y)."""
    t = (HI[1] - origin[1]) / direction[1]
    return origin + t * direction


def fermat_entry(lp, X, eta):
    """Where the light's path from lp to X (inside, below the top face y = HI[1]) refracts, by Fermat's
    principle: the path lies in the vertical plane through both, Q(s) on the line between their feet,
    where the derivative of the optical length o + eta k vanishes (brentq)."""
    from scipy import optimize

    fl, fx = np.array([lp[0], HI[1], lp[2]]), np.array([X[0], HI[1], X[2]])
    du = fx - fl
    if np.linalg.norm(du) < 1e-13:
        return fl

    def slope(s_):
        Q = fl + s_ * du
        return float((Q - lp) @ du) / np.linalg.norm(Q - lp) + eta * float((Q - X) @ du) / np.linalg.norm(Q - X)
    return fl + optimize.brentq(slope, 0.0, 1.0, xtol=1e-16, rtol=1e-15) * du


def level_crossings(cos, ell, spot, n=300):
    """The x in (0, ell) where cos(x) crosses the spot's levels (bracketed on n points, brentq)."""
    from scipy import optimize

    if spot is None:
        return []
    xs = np.linspace(0.0, ell, n + 1)[1:]
    cs = np.array([cos(x) for x in xs])
    out = []
    for level in spot[1:]:
        vals = cs - level
        for i in np.nonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))[0]:
            out.append(optimize.brentq(lambda x: cos(x) - level, xs[i], xs[i + 1], xtol=1e-15, rtol=1e-15))
    return sorted(out)


CUTS = {}  # the refracted twin's crossings of a spot's levels, per segment


def refracted_lamp(p, w, n, ell, lp, inten, eta, kt, ks, name, g, kt_out, spot=None):
    """Single scattering from a point (or spot) light through the refractive top face: the light's
    path by Fermat's principle (`fermat_entry`), the irradiance across the refracted beam from the ray
    tube by central differences (E = I T dOmega / dA), a spot's falloff toward the entry point Q, scipy
    quad in x on the pieces between the falloff's kinks."""
    def at(x):
        X = p + x * w
        Q = fermat_entry(lp, X, eta)
        e0 = (Q - lp) / np.linalg.norm(Q - lp)
        t0, ti, tt = snell(e0, n, eta)
        k = np.linalg.norm(Q - X)
        assert np.allclose(Q + k * t0, X, atol=1e-9), "Fermat's path misses the point"
        p1 = np.cross(e0, [0.0, 0.0, 1.0])
        p1 /= np.linalg.norm(p1)
        p2 = np.cross(e0, p1)
        delta = 1e-5

        def landing(da, db):  # the perturbed ray on the plane through X across the central refracted ray
            e = e0 + da * p1 + db * p2
            e /= np.linalg.norm(e)
            q2 = plane_hit(lp, e, n)
            t2, _, _ = snell(e, n, eta)
            return q2 + t2 * float((X - q2) @ t0) / float(t2 @ t0)
        j1 = (landing(delta, 0) - landing(-delta, 0)) / (2 * delta)
        j2 = (landing(0, delta) - landing(0, -delta)) / (2 * delta)
        area = np.linalg.norm(np.cross(j1, j2))  # dA / dOmega (p1, p2 span a unit solid angle to first order)
        e_irr = inten * fresnel_t(ti, tt, eta) * oracle.emission(spot, e0) / area
        return ks * oracle.phase(name, g, float(-(t0 @ w))) * e_irr * math.exp(
            -kt * (x + k) - kt_out * np.linalg.norm(Q - lp))

    def cos(x):
        Q = fermat_entry(lp, p + x * w, eta)
        return float((Q - lp) @ spot[0]) / np.linalg.norm(Q - lp)
    key = (p.tobytes(), w.tobytes(), lp.tobytes(), eta, spot is None or spot[1:])
    if key not in CUTS:  # the same for every channel
        CUTS[key] = level_crossings(cos, ell, spot)
    edges = [0.0, *CUTS[key], ell]
    return sum(integrate.quad(at, a, b, epsabs=0.0, epsrel=1e-10, limit=100)[0] for a, b in zip(edges, edges[1:]))


def twin_pixel(scene, i, j, approx=False):
    cam, shape, light = scene["camera"], scene["shape"][0], scene["light"][0]
    inner = shape["interior"]
    eta = inner.get("ior", 1.0)
    ks = np.broadcast_to(np.array(inner["sigma_s"], float), 3)
    kt = np.broadcast_to(np.array(inner["sigma_a"], float), 3) + ks
    kt_out = np.broadcast_to(np.array(scene.get("medium", {}).get("sigma_a", 0.0), float), 3)
    ph = inner.get("phase", "isotropic")
    name, g = (ph, 0.0) if isinstance(ph, str) else (ph["type"], ph["g"])
    lo, hi = np.array(shape["min"], float), np.array(shape["max"], float)
    strict = not scene.get("any_face", False)
    o, d = oracle.camera_ray(cam, i, j)
    t, n = box_entry(o, d, lo, hi)
    if n is None:
        return np.zeros(3)
    p = o + t * d
    w, ti, tt = snell(d, n, eta)
    into = fresnel_t(ti, tt, eta) / eta**2
    ell, _ = oracle.box_exit(p, w, lo, hi)
    out = np.zeros(3)
    spot = oracle.spot_of(light)
    if spot is not None and eta == 1.0:
        edges = [0.0, *sorted(oracle.cone_crossings(p, w, ell, np.array(light["position"], float), spot)), ell]
    else:
        edges = [0.0, ell]
    for c in range(3):
        if light["type"] == "directional":
            s = np.array(light["direction"], float)
            s /= np.linalg.norm(s)
            ts, si, st = snell(s, n, eta)
            e_in = light["irradiance"] * fresnel_t(si, st, eta) * math.cos(si) / math.cos(st)
            phase = oracle.phase(name, g, float(-(ts @ w)))

            def f(x):
                return ks[c] * phase * e_in * math.exp(-kt[c] * (x + back_to_boundary(p + x * w, -ts, n, lo, hi,
                                                                                        strict)))
        elif eta != 1.0:
            out[c] = refracted_lamp(p, w, n, ell, np.array(light["position"], float), light["intensity"], eta, kt[c],
                                    ks[c], name, g, kt_out[c], oracle.spot_of(light))
            continue
        else:
            lp = np.array(light["position"], float)
            inten = light["intensity"]

            def f(x):
                X = p + x * w
                dist = np.linalg.norm(lp - X)
                k = min(back_to_boundary(X, (lp - X) / dist, n, lo, hi, strict), dist)
                mu = float((X - lp) @ -w) / dist
                return (ks[c] * oracle.phase(name, g, mu) * inten * oracle.emission(spot, (X - lp) / dist)
                        * math.exp(-kt[c] * (x + k) - kt_out[c] * (dist - k)) / dist**2)
            if approx:  # the seed's sec. 4.2 with c, the phase and the outside attenuation at the entry point
                da = np.linalg.norm(lp - p)
                cc = float(-(w @ n)) / float((lp - p) @ n / da)
                q = kt[c] * (1 + cc)
                inv = integrate.quad(lambda x: 1.0 / np.sum((lp - p - x * w) ** 2), 0.0, ell, epsabs=0.0,
                                     epsrel=1e-13)[0]
                mu0 = float((p - lp) @ -w) / da
                out[c] = (inten * ks[c] * oracle.phase(name, g, mu0) * (-math.expm1(-q * ell)) / (q * ell) * inv
                          * math.exp(-kt_out[c] * da))
                continue
        out[c] = sum(integrate.quad(f, a, b, epsabs=0.0, epsrel=1e-12, limit=200)[0] for a, b in zip(edges, edges[1:]))
    return into * out * np.exp(-kt_out * t)


def scene(light, ior=1.0, phase="isotropic", medium=None, shape_extra=None):
    s = {"name": "bounded",
         "camera": {"position": [0.3, 2.0, 3.0], "look_at": [0.0, -1.0, 0.0], "fov": 40.0, "width": 6, "height": 4,
                    "spp": 1},
         "shape": [{"primitive": "box", "min": LO.tolist(), "max": HI.tolist(),
                    "interior": {"sigma_a": [0.3, 0.05, 0.02], "sigma_s": [0.1, 0.2, 0.05], "phase": phase, "ior": ior},
                    **(shape_extra or {})}],
         "light": [light]}
    if medium:
        s["medium"] = medium
    return s


SUN = {"type": "directional", "direction": [0.3, -1.0, -0.4], "irradiance": 2.0}
LAMP = {"type": "point", "position": [1.0, 3.0, 0.5], "intensity": 5.0}
CASES = {
    "sun_refracted": scene(SUN, ior=1.33, phase={"type": "hg", "g": 0.7}),
    "sun_index_matched": scene(SUN),
    "sun_dense_glass": scene(SUN, ior=2.4, phase="rayleigh"),
    "lamp_index_matched": scene(LAMP, phase={"type": "hg", "g": -0.3}, medium={"sigma_a": 0.02}),
    "lamp_refracted": scene(LAMP, ior=1.5, phase={"type": "hg", "g": 0.4}, medium={"sigma_a": 0.02}),
}


def beside_cube(light):
    """A small index-matched cube seen on two faces, lit from beside: light paths leave through any face."""
    s = scene(light, phase={"type": "hg", "g": 0.5})
    s["shape"][0].update(min=[-0.5, -1.0, -0.5], max=[0.5, 0.0, 0.5])
    s["camera"].update(position=[1.0, 0.8, 1.8], look_at=[0.0, -0.5, 0.0], width=12, height=8)
    s["any_face"] = True  # for the twin only
    return s


CUBES = {"lamp_beside_cube": beside_cube({"type": "point", "position": [1.2, -0.3, 0.4], "intensity": 5.0}),
         "sun_beside_cube": beside_cube({"type": "directional", "direction": [-0.8, -0.5, -0.3], "irradiance": 2.0})}


def spot(position, look_at, cone, start):
    return {"type": "spot", "position": position, "look_at": look_at, "intensity": 5.0, "cone_angle": cone,
            "falloff_start": start}


ABOVE = spot([1.0, 3.0, 0.5], [0.0, -3.0, -1.0], 20.0, 12.0)  # the beam's edge crosses the box under the view
BESIDE = [1.2, -0.3, 0.4]
SPOTS = {"spot_index_matched": scene(ABOVE, phase={"type": "hg", "g": -0.3}, medium={"sigma_a": 0.02}),
         "spot_refracted": scene(ABOVE, ior=1.5, phase={"type": "hg", "g": 0.4}, medium={"sigma_a": 0.02}),
         "spot_hard_refracted": scene(ABOVE | {"falloff_start": 20.0}, ior=1.33, medium={"sigma_a": 0.02}),
         "spot_beside_cube": beside_cube(spot(BESIDE, [-0.5, -0.6, -0.2], 25.0, 15.0)),
         "spot_hard_cube": beside_cube(spot(BESIDE, [-0.5, -0.6, -0.2], 20.0, 20.0)),
         "spot_away_cube": beside_cube(spot(BESIDE, [3.0, -0.3, 0.4], 60.0, 50.0))}


def image(case, method, params=None):
    sc = dict((CASES | CUBES | SPOTS)[case])
    sc.pop("any_face", None)
    prep = prepare(scene_from_text(to_toml(sc), case))
    return render(prep, method, params or {}, RenderOptions(threads=1)).image


def twin_image(case, approx=False):
    sc = (CASES | CUBES | SPOTS)[case]
    return np.array([[twin_pixel(sc, i, j, approx) for i in range(sc["camera"]["width"])]
                     for j in range(sc["camera"]["height"])])


@pytest.mark.parametrize("case", sorted(CASES))
def test_quadrature_matches_the_twin(case):
    """1e-9 (through a refractive boundary from a point light the twin's irradiance is a
    finite-difference ray tube, good to about 1e-10: measured agreement 6e-11)."""
    ref = twin_image(case)
    assert np.all(ref > 0)
    img = image(case, "quadrature")
    assert np.max(np.abs(img - ref) / ref) < 1e-9


@pytest.mark.parametrize("case", [c for c in sorted(CASES) if c.startswith("sun")])
def test_analytic_eq5_matches_the_twin(case):
    ref = twin_image(case)
    assert np.max(np.abs(image(case, "analytic") - ref) / ref) < 1e-9


def test_slab_approx_is_the_seeds_approximation():
    ref = twin_image("lamp_index_matched", approx=True)
    img = image("lamp_index_matched", "slab_approx")
    assert np.max(np.abs(img - ref) / ref) < 1e-9
    exact = twin_image("lamp_index_matched")
    assert np.all(img < exact)  # too dark near the light, as seed002's sweep measures (-6 % .. -99 %)


def test_exit_continues_to_what_lies_behind():
    """ior = 1 and no scattering inside: the box only absorbs; a lit wall below it is seen through
    it, attenuated by exp(-kt ell) over the inside length (the surface term itself unchanged)."""
    base = scene(LAMP)
    base["camera"].update(position=[0.2, 2.0, 0.3], look_at=[0.0, -3.0, 0.0])
    base["shape"][0].update(min=[-1.0, -1.0, -1.0], max=[1.0, 0.0, 1.0], interior={"sigma_a": 0.2, "sigma_s": 0.0})
    base["shape"].append({"primitive": "quad",
                          "corners": [[-9.0, -3.0, -9.0], [9.0, -3.0, -9.0], [9.0, -3.0, 9.0], [-9.0, -3.0, 9.0]]})
    base["light"] = [{"type": "point", "position": [3.0, -1.5, 0.0], "intensity": 5.0}]  # below the box: no shadow
    with_box = render(prepare(scene_from_text(to_toml(base), "t")), "quadrature", {}, RenderOptions(threads=1)).image
    base["shape"] = base["shape"][1:]
    without = render(prepare(scene_from_text(to_toml(base), "t")), "quadrature", {}, RenderOptions(threads=1)).image
    assert np.all(without > 0)
    lo, hi = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 0.0, 1.0])
    crossed = 0
    for j in range(4):
        for i in range(6):  # the twin: the camera ray's length inside the box, by the slab test
            o, d = oracle.camera_ray(base["camera"], i, j)
            with np.errstate(divide="ignore"):
                ts = (lo - o) / d, (hi - o) / d
            inside = max(0.0, np.min(np.maximum(*ts)) - max(np.max(np.minimum(*ts)), 0.0))
            crossed += inside > 0
            assert with_box[j, i] == pytest.approx(without[j, i] * math.exp(-0.2 * inside), rel=1e-9)
    assert crossed >= 12


def bad(scene_dict, method="quadrature"):
    with pytest.raises(UserError) as err:
        render(prepare(scene_from_text(to_toml(scene_dict), "bad.toml")), method, {}, RenderOptions(threads=1))
    msg = str(err.value)
    assert "\n" not in msg
    return msg


def test_bad_input_is_refused_in_one_line(tmp_path):
    open_quad = scene(SUN)
    open_quad["shape"][0] = {"primitive": "quad", "corners": [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]],
                             "interior": {"sigma_s": 0.1}}
    assert "4 boundary edges" in bad(open_quad)
    with pytest.raises(UserError, match=r"interior\.ior: must be positive"):
        scene_from_text(to_toml(scene(SUN, ior=0.0)), "bad.toml")
    inside = scene(SUN, ior=1.33)
    inside["camera"]["position"] = [0.0, -0.5, 2.0]
    assert "camera.position: inside shape[0]" in bad(inside, "slab_approx")  # the entry plane's model
    inside["shape"][0]["interior"]["ior"] = 1.0
    assert "camera.position: inside shape[0]" in bad(inside, "slab_approx")
    assert "--method lecocq" in bad(scene(SUN), "lecocq")
    assert "no closed form" in bad(scene(LAMP), "analytic")
    assert "index-matched boundaries with point lights" in bad(scene(LAMP, ior=1.5), "slab_approx")
    with pytest.raises(UserError, match="unknown key"):
        scene_from_text(to_toml(scene(SUN)).replace("ior = 1.0", "iorr = 1.0"), "bad.toml")
    # the command line: exit 2, one line, nothing written
    path = tmp_path / "open.toml"
    path.write_text(to_toml(open_quad))
    out = tmp_path / "o.exr"
    assert main(["render", str(path), "--out", str(out)]) == 2
    assert not out.exists()


@pytest.mark.parametrize("case", ["sun_refracted", "lamp_index_matched", "lamp_refracted"])
def test_raymarch_and_montecarlo_inside(case):
    """Ray marching converges as O(h^2) (midpoint rule); Monte Carlo free-path samples are unbiased:
    mean squared z-score against the twin, with the render's own variance, about 1."""
    ref = twin_image(case)
    errs = [np.max(np.abs(image(case, "raymarch", {"steps": n}) - ref) / ref) for n in (64, 128)]
    assert errs[1] < 1e-3 and 3.5 < errs[0] / errs[1] < 4.5, errs
    prep = prepare(scene_from_text(to_toml(CASES[case]), case))
    res = render(prep, "montecarlo", {"samples": 64}, RenderOptions(seed=7, threads=1))
    assert np.all(res.variance > 0)
    z2 = np.mean((res.image - ref) ** 2 / res.variance)
    assert z2 < 3.5
    assert np.mean(ref**2 / res.variance) > 3.5  # an all-zero image would fail


def test_describe_shows_the_interior(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(to_toml(CASES["sun_refracted"]))
    assert main(["describe", str(path)]) == 0
    assert "shape[0].interior: sigma_a [0.3, 0.05, 0.02], sigma_s [0.1, 0.2, 0.05], phase hg g=0.7, ior 1.33" in \
        capsys.readouterr().out


@pytest.mark.parametrize("name,method", [("ocean", "analytic"), ("wax", "slab_approx")])
def test_bundled_scenes_render(tmp_path, name, method):
    """The bundled ocean and wax scenes, tiny, by name: finite, lit, and the same as quadrature where
    the method is exact (eq. 5 over the ocean's planar surface)."""
    import raytrace

    img = raytrace.render(name, method=method, width=8, height=6).array
    ref = raytrace.render(name, method="quadrature", width=8, height=6).array
    assert np.all(np.isfinite(img)) and img.max() > 0
    if name == "ocean":
        lit = ref > 0
        assert np.max(np.abs(img - ref)[lit] / ref[lit]) < 1e-9
    else:  # the seed's approximation differs visibly on the block (its error is measured by seed002)
        assert np.max(np.abs(img - ref) / np.maximum(ref, 1e-300)) > 0.1


@pytest.mark.parametrize("case", sorted(CUBES))
def test_convex_index_matched_shapes_trace_the_exact_straight_path(case):
    """A cube lit from beside: the light's paths leave through whichever face they meet (the twin
    measures them on the actual cube); quadrature to 1e-9, ray marching O(h^2), where the seed's entry
    plane (slab_approx: eq. 5 for the sun) is off."""
    ref = twin_image(case)
    lit = ref > 0
    assert lit.sum() >= 30
    img = image(case, "quadrature")
    assert np.all(img[~lit] == 0) and np.max(np.abs(img - ref)[lit] / ref[lit]) < 1e-9
    errs = [np.max(np.abs(image(case, "raymarch", {"steps": n}) - ref)[lit] / ref[lit]) for n in (256, 512)]
    assert 3.0 < errs[0] / errs[1] < 6.0 and errs[1] < 1e-5, errs  # O(h^2) (kinks where the exit face changes)
    plane = image(case, "slab_approx")
    assert np.max(np.abs(plane - ref)[lit] / ref[lit]) > 0.05


ROCK_LO, ROCK_HI = np.array([-0.3, -0.8, -0.3]), np.array([0.3, -0.4, 0.3])
WATER_LO, WATER_HI = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 0.0, 1.0])


def slab(o, d, lo, hi):
    """(t_in, t_out, normal at t_in) of the line o + t d through the box [lo, hi] (t_in may be < 0), or None."""
    t0, t1, n0 = -math.inf, math.inf, None
    for a in range(3):
        if d[a] == 0.0:
            if not lo[a] <= o[a] <= hi[a]:
                return None
            continue
        ta, tb = (lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]
        if min(ta, tb) > t0:
            t0, n0 = min(ta, tb), np.eye(3)[a] * (-1.0 if ta < tb else 1.0)
        t1 = min(t1, max(ta, tb))
    return (t0, t1, n0) if t0 < t1 else None


SUN_HIGH = {"type": "directional", "direction": [0.4, -1.0, -0.3], "irradiance": 2.0}


ROCK_SPOT = {"type": "spot", "position": [1.0, 3.0, 0.5], "look_at": [-0.3, -0.6, -0.1], "intensity": 5.0,
             "cone_angle": 9.0, "falloff_start": 5.0}  # the beam's edge across the rock


LID_Y, LID_X = 2.5, (-3.0, -1.05)  # an opaque lid above the camera, x in LID_X, z in [-3, 3], over part of the tank


def under_lid(R, s_dir):
    """Whether the sun's path back from R (along -s_dir) meets the lid."""
    t = (LID_Y - R[1]) / -s_dir[1]
    x, z = R[0] - t * s_dir[0], R[2] - t * s_dir[2]
    return LID_X[0] <= x <= LID_X[1] and -3.0 <= z <= 3.0


def water_beams(sun, X, n, ior, kt, lid=False):
    """E_in cos exp(-kt k) (3,) at the point X (normal n) inside the water box from a directional light
    refracted through every face it meets: face f's beam (Snell by angles, Fresnel angle form,
    E T cos_i / cos_t) where X's path back along it leaves the box through f, at distance k, and
    (`lid`) the sun's leg outside from there misses the lid."""
    s_dir = np.array(sun["direction"], float) / np.linalg.norm(sun["direction"])
    faces = [(np.eye(3)[a] * sign, WATER_HI[a] if sign > 0 else -WATER_LO[a]) for a in range(3) for sign in (1.0, -1.0)]
    out = np.zeros(3)
    for nf, _ in faces:
        if s_dir @ nf >= 0.0:
            continue
        ts, si, st = snell(s_dir, nf, ior)
        u = -ts
        dist = [((c - f @ X) / (f @ u), i) for i, (f, c) in enumerate(faces) if f @ u > 0.0]
        k, leaves = min(dist)
        if faces[leaves][0] @ nf < 1.0 or (lid and under_lid(X + k * u, s_dir)):
            continue
        e = sun["irradiance"] * fresnel_t(si, st, ior) * math.cos(si) / math.cos(st)
        out += e * max(float(n @ u), 0.0) * np.exp(-kt * k)
    return out


@pytest.mark.parametrize("light,ior,lid", [(LAMP, 1.0, False), (SUN_HIGH, 1.0, False), (SUN_HIGH, 1.33, False),
                                           (SUN_HIGH, 1.33, True), (ROCK_SPOT, 1.0, False)])
def test_a_surface_inside_a_medium_is_lit_through_it(light, ior, lid):
    """A rock (a plain box) inside an absorbing box of water seen through it. Index-matched: its shadow
    rays leave through the medium, rho / pi E cos exp(-sigma_t k - sigma_out (d - k)) exp(-sigma_t ell),
    the twin's lengths by the slab test. Refractive (ior 1.33): the sun refracted through every face
    of the box it meets (`water_beams`; until the underwater camera it was the entry face's plane
    alone, which gave points lit through a side face the top's beam; with a lid above the tank, the
    beams whose leg outside it covers are shadowed), the radiance x T / eta^2 out; 1e-9."""
    kt, kt_out = np.array([0.3, 0.1, 0.05]), (0.02 if light["type"] != "directional" else 0.0)
    sc = {"camera": {"position": [0.3, 2.0, 3.0], "look_at": [0.0, -0.6, 0.0], "fov": 16.0, "width": 12,
                     "height": 9, "spp": 1},
          "medium": {"sigma_a": kt_out},
          "shape": [{"primitive": "box", "min": WATER_LO.tolist(), "max": WATER_HI.tolist(),
                     "interior": {"sigma_a": kt.tolist(), "sigma_s": 0.0, "ior": ior}},
                    {"primitive": "box", "min": ROCK_LO.tolist(), "max": ROCK_HI.tolist(), "reflectance": 0.7}],
          "light": [light]}
    if lid:
        sc["shape"].append({"primitive": "quad", "corners": [[LID_X[0], LID_Y, -3.0], [LID_X[1], LID_Y, -3.0],
                                                             [LID_X[1], LID_Y, 3.0], [LID_X[0], LID_Y, 3.0]]})
    img = render(prepare(scene_from_text(to_toml(sc), "rock")), "quadrature", {}, RenderOptions(threads=1)).image
    rocks = partial = 0
    for j in range(9):
        for i in range(12):
            o, d = oracle.camera_ray(sc["camera"], i, j)
            t_water, n_in = box_entry(o, d, WATER_LO, WATER_HI)
            P = o + t_water * d
            w, ti, tt = snell(d, n_in, ior)
            hit = slab(P, w, ROCK_LO, ROCK_HI)
            if hit is None:
                assert np.all(img[j, i] == 0.0)
                continue
            rocks += 1
            ell, _, n = hit
            X = P + ell * w
            if light["type"] != "directional":
                u, dist, e, fall = oracle.lamp_at(light, X)
                partial += 0.0 < fall < 1.0
                k = slab(X, u, WATER_LO, WATER_HI)[1]
                att = np.exp(-kt * k - kt_out * (dist - k))
            elif ior == 1.0:
                u = -np.array(light["direction"], float) / np.linalg.norm(light["direction"])
                e, att = light["irradiance"], np.exp(-kt * slab(X, u, WATER_LO, WATER_HI)[1])
            else:
                e, att, u = 1.0, water_beams(light, X, n, ior, kt, lid), n
            want = (0.7 / math.pi * e * max(float(n @ u), 0.0) * att * np.exp(-kt * ell - kt_out * t_water)
                    * fresnel_t(ti, tt, ior) / ior**2)
            assert img[j, i] == pytest.approx(want, rel=1e-9, abs=1e-300), (i, j)
    assert rocks >= 15 and np.count_nonzero(img[..., 0]) >= 10
    assert light["type"] != "spot" or partial >= 5


def rock_in_dented_box(light):
    """A rock inside a refractive box whose top's centre is pushed 0.3 down (not convex): lit through every
    triangle under a lamp or a spot (tests/test_surfaces_nonconvex.py; refused until stop 60)."""
    sc = scene(light, ior=1.33)
    lo, hi = (-1.2, -1.8, -1.2), (1.2, 0.6, 1.2)
    corners = [[x, y, z] for y in (lo[1], hi[1]) for x, z in ((lo[0], lo[2]), (hi[0], lo[2]), (hi[0], hi[2]),
                                                               (lo[0], hi[2]))]
    faces = [[0, 1, 2], [0, 2, 3], [4, 7, 8], [7, 6, 8], [6, 5, 8], [5, 4, 8], [0, 5, 1], [0, 4, 5], [3, 2, 6],
             [3, 6, 7], [0, 3, 7], [0, 7, 4], [1, 5, 6], [1, 6, 2]]
    sc["shape"][0] = {"primitive": "triangles", "vertices": corners + [[0.0, 0.3, 0.0]], "faces": faces,
                      "interior": sc["shape"][0]["interior"]}
    sc["shape"].append({"primitive": "box", "min": [-0.3, -0.8, -0.3], "max": [0.3, -0.4, 0.3]})
    return sc


def as_point(case):
    """The twin's image of `case` with its spot replaced by a point light of the same intensity."""
    sc = dict(SPOTS[case])
    light = sc["light"][0]
    sc["light"] = [{"type": "point", "position": light["position"], "intensity": light["intensity"]}]
    return np.array([[twin_pixel(sc, i, j) for i in range(sc["camera"]["width"])]
                     for j in range(sc["camera"]["height"])])


@pytest.mark.parametrize("case", [c for c in sorted(SPOTS) if "away" not in c])
def test_spot_lights_into_bounded_media_match_the_twin(case):
    """A spot light's emission toward a point inside is the point light's times the falloff on the
    direction it leaves the spot in: the straight direction in index-matched shapes (the box's and the
    cube's convex kernel), the direction to Fermat's entry point through a refractive face. The twin
    (oracle.emission, its own crossings of the cone by brentq, Fermat by brentq) and quadrature agree
    to 1e-9 where lit and both are 0 elsewhere; the beam's edge crosses the inside segments (pixels
    between dark and the point light's value)."""
    CUTS.clear()
    ref = twin_image(case)
    if SPOTS[case]["shape"][0]["interior"]["ior"] == 1.0:
        point = as_point(case)
        partial = np.count_nonzero(np.all((ref > 1e-3 * point) & (ref < 0.999 * point), axis=2))
    else:  # the twin's Fermat paths are slow: count the segments its cone crossings cut instead
        partial = sum(len(cuts) > 0 for cuts in CUTS.values())
    assert partial >= 3 and np.count_nonzero(ref[..., 0] > 0) >= 3
    img = image(case, "quadrature")
    lit = ref > 0
    assert np.all(img[~lit] == 0) and np.max(np.abs(img - ref)[lit] / ref[lit]) < 1e-9


@pytest.mark.parametrize("case", ["spot_beside_cube", "spot_hard_refracted"])
def test_spot_lights_raymarch_and_montecarlo(case):
    """Ray marching converges (O(h^2) with the smooth falloff, O(h) across a hard edge); Monte Carlo's
    mean squared z-score against the twin is about 1."""
    ref = twin_image(case)
    lit = ref > 0
    errs = [np.max(np.abs(image(case, "raymarch", {"steps": n}) - ref)[lit] / ref[lit]) for n in (64, 256)]
    assert errs[0] / errs[1] > (10.0 if "hard" not in case else 3.0) and errs[1] < 1e-2, errs
    sc = dict(SPOTS[case])
    sc.pop("any_face", None)
    res = render(prepare(scene_from_text(to_toml(sc), case)), "montecarlo", {"samples": 64},
                 RenderOptions(seed=11, threads=1))
    z2 = np.mean((res.image - ref)[lit] ** 2 / res.variance[lit])
    assert z2 < 3.5 and np.mean(ref[lit] ** 2 / res.variance[lit]) > 3.5


def test_a_spot_aimed_away_leaves_the_medium_black():
    for method, params in (("quadrature", {}), ("raymarch", {"steps": 16}), ("montecarlo", {"samples": 8})):
        assert np.all(image("spot_away_cube", method, params) == 0.0), method


def test_spot_lights_without_a_method_for_them_are_refused():
    assert "no closed form" in bad(SPOTS["spot_index_matched"], "analytic")
    assert "not spot lights" in bad(SPOTS["spot_index_matched"], "slab_approx")
    # refractive, fog outside: a spot in a convex mesh lights it through the faces (tests/test_lantern_fog_spot.py),
    # one in an exact sphere within radius / ior of its centre too (tests/test_globe_bounds.py), not one beyond (the
    # critical angle's cones and the caustic are not cut: support._globe_fog)
    inside = scene(spot([0.0, -3.2, 0.0], [0.0, -3.4, 0.0], 30.0, 20.0), ior=1.33,
                   medium={"sigma_a": 0.02, "sigma_s": 0.05})
    inside["shape"][0] = {"primitive": "sphere", "center": [0.0, -1.5, 0.0], "radius": 2.0, "exact": True,
                          "interior": inside["shape"][0]["interior"]}
    assert "only from within radius / ior (1.50376) of its centre" in bad(inside)
