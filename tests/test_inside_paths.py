"""Non-convex index-matched shapes (raytrace/interiors/paths.py) against an independent twin.

The shape is a U-shaped prism (a closed OBJ mesh written here), the union of three boxes. The twin
knows only the boxes: a segment's length inside the U is the sum of its slab-test lengths in the
boxes (their interiors are disjoint), so a light path that leaves one arm and re-enters the other
is measured without any mesh or Embree. The camera ray's inside stretches and its transmittance
follow from the same lengths; scipy `quad` integrates the single scattering along the camera ray.
"""
import math

import numpy as np
import pytest
from scipy import integrate

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import load_scene

from . import oracle
from .conftest import to_toml

Z0, Z1 = -0.5, 0.5
BOXES = [((-1.0, -1.0), (1.0, -0.5)), ((-1.0, -0.5), (-0.4, 0.5)), ((0.4, -0.5), (1.0, 0.5))]
# the U's outline in the xy-plane, counter-clockwise (the points where the arms meet the base included)
OUTLINE = [(-1, -1), (1, -1), (1, -0.5), (1, 0.5), (0.4, 0.5), (0.4, -0.5), (-0.4, -0.5), (-0.4, 0.5), (-1, 0.5),
           (-1, -0.5)]
CAP = [(0, 1, 2), (0, 2, 5), (0, 5, 6), (0, 6, 9), (9, 6, 7), (9, 7, 8), (2, 3, 4), (2, 4, 5)]


def u_obj() -> str:
    v = [f"v {x} {y} {z}" for z in (Z0, Z1) for x, y in OUTLINE]
    m = len(OUTLINE)
    f = [f"f {a + 1} {c + 1} {b + 1}" for a, b, c in CAP] + [f"f {a + m + 1} {b + m + 1} {c + m + 1}" for a, b, c in CAP]
    for i in range(m):
        j = (i + 1) % m
        f += [f"f {i + 1} {j + 1} {j + m + 1}", f"f {i + 1} {j + m + 1} {i + m + 1}"]
    return "\n".join(v + f) + "\n"


def box_length(o, d, a, b, lo, hi):
    """Length of the part of o + t d, t in [a, b], inside the box [lo, hi] (slab test)."""
    t0, t1 = a, b
    for k in range(3):
        if d[k] == 0.0:
            if not lo[k] <= o[k] <= hi[k]:
                return 0.0
            continue
        ta, tb = (lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]
        t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
    return max(t1 - t0, 0.0)


def boxes3():
    return [(np.array([x0, y0, Z0]), np.array([x1, y1, Z1])) for (x0, y0), (x1, y1) in BOXES]


def u_length(o, d, a, b):
    return sum(box_length(o, d, a, b, lo, hi) for lo, hi in boxes3())


def u_stretches(o, d):
    """The camera ray's stretches inside the U: (t0, t1) merged across the boxes' shared faces."""
    iv = []
    for lo, hi in boxes3():
        with np.errstate(divide="ignore"):
            ts = (lo - o) / d, (hi - o) / d
        t0, t1 = max(np.max(np.minimum(*ts)), 0.0), np.min(np.maximum(*ts))
        if t1 > t0:
            iv.append([t0, t1])
    iv.sort()
    out = []
    for t0, t1 in iv:
        if out and t0 <= out[-1][1] + 1e-12:
            out[-1][1] = max(out[-1][1], t1)
        else:
            out.append([t0, t1])
    return out


KS, KA, KT_OUT = np.array([0.4, 0.6, 0.2]), np.array([0.3, 0.05, 0.02]), 0.05
G = 0.3


def u_scene(light):
    """The U (seen from above and in front; the light's paths leave one arm and enter the other) in an
    absorbing outside (a vacuum for the directional light, which would get no light through an
    absorbing outside filling all space)."""
    return {"camera": {"position": [0.3, 1.4, 3.0], "look_at": [0.0, -0.3, 0.0], "fov": 45.0, "width": 10,
                       "height": 7, "spp": 1},
            "medium": {"sigma_a": KT_OUT if light["type"] != "directional" else 0.0},
            "shape": [{"mesh": "u.obj", "interior": {"sigma_a": KA.tolist(), "sigma_s": KS.tolist(),
                                                      "phase": {"type": "hg", "g": G}}}],
            "light": [light]}


LAMP = {"type": "point", "position": [1.6, 0.25, 0.1], "intensity": 3.0}  # beside the right arm: through both arms
SUN = {"type": "directional", "direction": [-1.0, -0.35, -0.2], "irradiance": 2.0}
# the lamp as a spot aimed across the U: its beam's edge crosses both arms
SPOT = LAMP | {"type": "spot", "look_at": [-0.3, -0.35, 0.0], "cone_angle": 22.0, "falloff_start": 14.0}
LIGHTS = {"lamp": LAMP, "sun": SUN, "spot": SPOT}
HARD = SPOT | {"falloff_start": 22.0}  # a hard-edged cone


def twin_pixel(sc, i, j):
    o, d = oracle.camera_ray(sc["camera"], i, j)
    light = sc["light"][0]
    kt, kt_out = KA + KS, sc["medium"]["sigma_a"]
    spot = oracle.spot_of(light)
    out = np.zeros(3)
    for t0, t1 in u_stretches(o, d):
        cuts = [x for x in oracle.cone_crossings(o, d, t1, np.array(light.get("position", [0.0] * 3), float), spot)
                if x > t0]
        edges = [t0, *sorted(cuts), t1]
        for c in range(3):
            def f(t):
                X = o + t * d
                inside = u_length(o, d, 0.0, t)
                tau = kt[c] * inside + kt_out * (t - inside)
                if light["type"] != "directional":
                    lp = np.array(light["position"], float)
                    dist = np.linalg.norm(lp - X)
                    u = (lp - X) / dist
                    k = u_length(X, u, 0.0, dist)
                    tau += kt[c] * k + kt_out * (dist - k)
                    e = light["intensity"] * oracle.emission(spot, -u) / dist**2
                else:
                    u = -np.array(light["direction"], float)
                    u /= np.linalg.norm(u)
                    tau += kt[c] * u_length(X, u, 0.0, 10.0)
                    e = light["irradiance"]
                return KS[c] * oracle.phase("hg", G, float(u @ d)) * e * math.exp(-tau)
            out[c] += sum(integrate.quad(f, a, b, epsabs=0.0, epsrel=1e-11, limit=400)[0]
                          for a, b in zip(edges, edges[1:]))
    return out


def setup(tmp_path, light):
    (tmp_path / "u.obj").write_text(u_obj())
    path = tmp_path / "u.toml"
    sc = u_scene(light)
    path.write_text(to_toml(sc))
    return sc, prepare(load_scene(path))


def twin_image(sc):
    return np.array([[twin_pixel(sc, i, j) for i in range(sc["camera"]["width"])]
                     for j in range(sc["camera"]["height"])])


@pytest.mark.parametrize("name", sorted(LIGHTS) + ["hard"])
def test_non_convex_shape_traces_paths_that_leave_and_reenter(tmp_path, name):
    """Quadrature to 1e-7 against the twin (measured 2e-12 for the lamp; 2e-8 for the sun, where the
    twin's own quad reports its limit and Embree's float32 decisions near the U's edges move lengths
    by ~1e-7), ray marching converging (at least O(h)), Monte Carlo unbiased (mean squared z). The
    spot's (smooth and hard-edged) beam edge crosses the U: some pixels are dark, some partly lit."""
    from raytrace.interiors.shapes import convex_planes

    sc, prep = setup(tmp_path, LIGHTS.get(name, HARD))
    assert not len(convex_planes(prep, 0))  # the traced path, not the convex kernel
    ref = twin_image(sc)
    lit = ref > 0
    assert lit.sum() >= 30
    if name in ("spot", "hard"):
        point = twin_image(u_scene(LAMP))
        assert np.count_nonzero((ref < 0.99 * point) & lit) >= 10 and np.count_nonzero(point > 0) > lit.sum()
    img = render(prep, "quadrature", {"rtol": 1e-10}, RenderOptions(threads=1)).image
    assert np.all(img[~lit] == 0) and np.max(np.abs(img - ref)[lit] / ref[lit]) < 1e-7
    errs = [np.max(np.abs(render(prep, "raymarch", {"steps": n}, RenderOptions(threads=1)).image - ref)[lit] / ref[lit])
            for n in (64, 128)]
    if name == "hard":  # the midpoint rule across a jump: O(h) (measured 1.4e-2, 7.6e-3)
        assert errs[0] / errs[1] > 1.5 and errs[1] < 2e-2, errs
    else:
        assert errs[0] / errs[1] > 2.0 and errs[1] < 1e-4, errs
    res = render(prep, "montecarlo", {"samples": 32}, RenderOptions(seed=3, threads=1))
    assert np.mean((res.image - ref)[lit] ** 2 / res.variance[lit]) < 3.5


@pytest.mark.parametrize("name", sorted(LIGHTS))
def test_a_camera_inside_the_medium(tmp_path, name):
    """The camera in the U's left arm looking across the notch into the right arm: the inside stretch
    from the camera, the way out, the notch and the way back in (the twin's stretches start at 0);
    quadrature 1e-7, Monte Carlo unbiased."""
    (tmp_path / "u.obj").write_text(u_obj())
    sc = u_scene(LIGHTS[name])
    sc["camera"].update(position=[-0.7, 0.1, 0.3], look_at=[1.0, -0.2, -0.2], fov=60.0, width=8, height=5)
    (tmp_path / "u.toml").write_text(to_toml(sc))
    prep = prepare(load_scene(tmp_path / "u.toml"))
    assert prep.camera_inside == 0
    ref = twin_image(sc)
    assert np.all(ref > 0)
    img = render(prep, "quadrature", {"rtol": 1e-10}, RenderOptions(threads=1)).image
    assert np.max(np.abs(img - ref) / ref) < 1e-7
    res = render(prep, "montecarlo", {"samples": 32}, RenderOptions(seed=5, threads=1))
    assert np.mean((res.image - ref) ** 2 / res.variance) < 3.5


def test_a_light_inside_a_refractive_medium_is_refused(tmp_path):
    """A lamp inside the U takes index-matched interiors only (tests/test_light_inside_non_convex.py):
    inside a refractive one its light would leave refracted (a caustic outside)."""
    import raytrace

    (tmp_path / "u.obj").write_text(u_obj())
    sc = u_scene({"type": "point", "position": [-0.7, 0.0, 0.0], "intensity": 1.0})
    sc["shape"][0]["interior"]["ior"] = 1.33
    (tmp_path / "u.toml").write_text(to_toml(sc))
    with pytest.raises(raytrace.UserError, match=r"light\[0\]\.position: inside shape\[0\]"):
        render(prepare(load_scene(tmp_path / "u.toml")), "quadrature", {}, RenderOptions(threads=1))


@pytest.mark.parametrize("name", sorted(LIGHTS))
def test_shadows_through_an_index_matched_interior_are_attenuated(tmp_path, name):
    F = 30.0  # the floor's half width
    """A lit floor under the U: where the straight shadow path crosses the U (through one arm, or out
    of one and into the other), the floor gets exp(-sigma_t x the length inside) of its unshadowed
    radiance (the twin: Lambert's law and the boxes' slab lengths); 1e-9."""
    light = dict(LIGHTS[name])
    if name != "sun":  # low beside the right arm: the shadow paths cross both arms and the notch
        light["position"] = [2.0, 0.4, 0.1]
        if name == "spot":
            light["look_at"] = [-8.0, -2.0, 0.0]  # the beam's edge across the lit floor
        view = [-14.0, 2.0, 2.0], [-8.0, -2.0, 0.0]
    else:
        light["direction"] = [-0.5, -1.0, -0.2]
        view = [-5.0, 3.0, 1.0], [-0.9, -2.0, -0.35]
    (tmp_path / "u.obj").write_text(u_obj())
    sc = u_scene(light)
    sc["medium"] = {"sigma_a": 0.0}
    sc["shape"].append({"primitive": "quad", "reflectance": 0.6,
                        "corners": [[-F, -2.0, -F], [F, -2.0, -F], [F, -2.0, F], [-F, -2.0, F]]})
    sc["camera"].update(position=view[0], look_at=view[1], width=16, height=12)
    (tmp_path / "u.toml").write_text(to_toml(sc))
    img = render(prepare(load_scene(tmp_path / "u.toml")), "quadrature", {}, RenderOptions(threads=1)).image
    kt = KA + KS
    shadowed = reentered = partial = 0
    for j in range(12):
        for i in range(16):
            o, d = oracle.camera_ray(sc["camera"], i, j)
            if u_stretches(o, d) or d[1] >= 0:
                continue  # the camera ray crosses the U or misses the floor
            X = o + (-2.0 - o[1]) / d[1] * d
            if np.max(np.abs(X)) > F:
                continue  # beyond the floor
            if light["type"] != "directional":
                u, dist, e, fall = oracle.lamp_at(light, X)
                partial += 0.0 < fall < 1.0 and u_length(X, u, 0.0, dist) > 0
            else:
                u = -np.array(light["direction"], float)
                u /= np.linalg.norm(u)
                dist, e = 10.0, light["irradiance"]
            inside = u_length(X, u, 0.0, dist)
            shadowed += inside > 0
            reentered += len(u_stretches(X, u)) > 1
            want = 0.6 / math.pi * e * u[1] * np.exp(-kt * inside)
            assert img[j, i] == pytest.approx(want, rel=1e-9, abs=0.0), (i, j, inside)
    assert shadowed >= 10 and reentered >= (1 if name == "sun" else 50)  # measured 141, 88 and 11, 2
    assert name != "spot" or partial >= 10  # shadowed floor pixels in the spot's falloff band
