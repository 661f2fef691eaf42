"""Area lights (issue 36): quad, disk and sphere emitters, each a cubature of LAMBERT spot rows
(raytrace/lights/area.py).

- The scene file: each kind parses and describes as SCENE_FORMAT.md pins it; bad input is one line
  naming the key and the fix, exit 2, nothing written; methods that do not take area lights refuse,
  naming those that do.
- The rows against scipy: their area weights sum to the area A (scipy's own integral of the
  parameter domain's Jacobian), the power they emit is pi L A one-sided and 2 pi L A two-sided
  (scipy over the sphere of directions of the rows' intensities max(0, n·u)), the points lie on
  the emitter; the LAMBERT band's trigonometric form (analytic's) equals max(c, 0).
- The emitter is a shape: a camera ray sees `radiance` on its front, black behind (unless two-sided),
  and it shadows a point light behind it; its own emitter points are not shadowed by it.
- Images against the brute-force twin (tests/area_twin.py: the geometry and scipy alone).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from raytrace import api, errors as raytrace_errors
from raytrace.cli import main
from raytrace.lights import LAMBERT, Lights, band_trig, cubature, describe, disk, falloff, power_of, quad, sphere
from raytrace.scene.format import scene_from_text

from . import area_twin as twin
from .conftest import to_toml

CAMERA = {"position": [0.0, 0.0, 4.0], "look_at": [0.0, 0.5, 0.0], "fov": 60.0, "width": 16, "height": 12}
QUAD = {"type": "quad", "corners": [[-0.5, 1.5, -0.5], [0.5, 1.5, -0.5], [0.5, 1.5, 0.5], [-0.5, 1.5, 0.5]],
        "radiance": 10.0}
DISK = {"type": "disk", "center": [0.0, 1.5, 0.0], "normal": [0.0, -1.0, 0.0], "radius": 0.5, "radiance": 10.0}
SPHERE = {"type": "sphere", "center": [0.0, 1.5, 0.0], "radius": 0.3, "radiance": 10.0}
FOG = {"sigma_a": 0.05, "sigma_s": 0.1}
KT, KS = 0.15, 0.1


def scene(lights, medium=FOG, camera=CAMERA, shapes=()):
    return scene_from_text(to_toml({"camera": camera, "shape": list(shapes), "light": lights, "medium": medium}),
                           "area.toml")


def test_each_area_kind_parses_and_describes():
    q, d, s = scene([QUAD, {**DISK, "two_sided": True, "radiance": [1.0, 2.0, 3.0]}, SPHERE]).lights
    np.testing.assert_array_equal(q.axis, [0.0, -1.0, 0.0])  # (c1 - c0) x (c3 - c0)
    assert q.emitter["area"] == 1.0 and not q.two_sided
    assert describe(q) == ("quad of corners [[-0.5, 1.5, -0.5], [0.5, 1.5, -0.5], [0.5, 1.5, 0.5], [-0.5, 1.5, 0.5]], "
                           f"normal [0.0, -1.0, 0.0], area 1, radiance [10.0, 10.0, 10.0], one-sided, power "
                           f"{[10.0 * math.pi] * 3} W")
    assert d.two_sided and d.emitter["area"] == math.pi * 0.25
    np.testing.assert_array_equal(power_of(d), 2.0 * math.pi * np.array([1.0, 2.0, 3.0]) * math.pi * 0.25)
    assert describe(s).startswith("sphere at [0.0, 1.5, 0.0], radius 0.3, radiance [10.0, 10.0, 10.0], one-sided")


def test_emitters_are_shapes_after_the_files_own():
    sc = scene([QUAD, DISK, SPHERE], shapes=[{"primitive": "box", "min": [-1.0, -1.0, -1.0], "max": [1.0, -0.9, 1.0]}])
    assert [s.kind for s in sc.shapes] == ["box", "quad", "triangles", "sphere"]
    assert [s.light for s in sc.shapes] == [None, 0, 1, 2]
    assert all(np.all(s.reflectance == 0.0) and np.all(s.emission == 10.0) for s in sc.shapes[1:])


@pytest.mark.parametrize("light,message", [
    ({**QUAD, "radiance": None}, "light[0].radiance: missing; add light[0].radiance = "),
    ({**QUAD, "corners": QUAD["corners"][:3]}, "light[0].corners: expected four [x, y, z] corners"),
    ({**QUAD, "corners": [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 2.0], [0.0, 0.0, 1.0]]},
     "light[0].corners[2]: is not c1 + c3 - c0 = [1.0, 0.0, 1.0]: the quad is not a parallelogram"),
    ({**QUAD, "corners": [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 0.0, 0.0]]},
     "light[0].corners: the corners have no area"),
    ({**QUAD, "two_sided": 1}, "light[0].two_sided: expected true or false"),
    ({**QUAD, "radiance": -1.0}, "light[0].radiance: must be >= 0.0"),
    ({**DISK, "normal": [0.0, 0.0, 0.0]}, "light[0].normal: is zero"),
    ({**DISK, "radius": 0.0}, "light[0].radius: must be positive"),
    ({**DISK, "center": None}, "light[0].center: missing"),
    ({**SPHERE, "two_sided": True}, "light[0].two_sided: unknown key"),
    ({**SPHERE, "radius": None}, "light[0].radius: missing"),
])
def test_bad_area_lights_are_one_line_errors(write_scene, tmp_path, capsys, light, message):
    light = {k: v for k, v in light.items() if v is not None}
    path = write_scene({"camera": CAMERA, "light": [light], "medium": FOG})
    out = tmp_path / "x.exr"
    assert main(["render", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and message in err, err
    assert not out.exists()


@pytest.mark.parametrize("method", ["lecocq", "sun"])
@pytest.mark.parametrize("light", [QUAD, DISK, SPHERE])
def test_methods_without_spot_lights_refuse_area_lights(write_scene, tmp_path, capsys, method, light):
    path = write_scene({"camera": CAMERA, "light": [light], "medium": FOG})
    out = tmp_path / "x.exr"
    assert main(["render", str(path), "--out", str(out), "--quiet", "--method", method]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"--method {method}: it does not take {light['type']} lights" in err, err
    assert "use --method analytic, quadrature, raymarch, montecarlo" in err, err
    assert not out.exists()


def _rows(light, order, two_sided=False):
    lt = scene([{**light, **({"two_sided": True} if two_sided else {})}]).lights[0]
    kind = {"quad": quad, "disk": disk, "sphere": sphere}[light["type"]]
    return lt, kind.rows(lt, order)


AREAS = {  # the area by scipy from each kind's parametrisation (Jacobian over the parameter domain)
    "quad": lambda lt: integrate.dblquad(lambda v, u: np.linalg.norm(np.cross(*(lt.emitter["corners"][[1, 3]]
                                                                                - lt.emitter["corners"][0]))),
                                         0, 1, 0, 1)[0],
    "disk": lambda lt: integrate.dblquad(lambda r, p: r, 0, 2 * math.pi, 0, lt.emitter["radius"])[0],
    "sphere": lambda lt: integrate.dblquad(lambda t, p: lt.emitter["radius"] ** 2 * math.sin(t), 0, 2 * math.pi, 0,
                                           math.pi)[0],
}


@pytest.mark.parametrize("light", [QUAD, DISK, SPHERE])
@pytest.mark.parametrize("order", [1, 3, 8])
def test_area_weights_sum_to_the_area(light, order):
    lt, rows = _rows(light, order)
    area = AREAS[light["type"]](lt)
    assert abs(rows.intensity[:, 0].sum() / lt.intensity[0] - area) <= 1e-12 * area
    assert np.all(rows.intensity > 0.0) and rows.cubature and np.all(rows.cone == [0.0, 1.0, LAMBERT])
    np.testing.assert_allclose(np.linalg.norm(rows.axis, axis=1), 1.0, rtol=1e-15)
    p = rows.position
    if light["type"] == "quad":
        assert np.all(np.abs(p[:, 1] - 1.5) == 0.0) and np.all(np.abs(p[:, [0, 2]]) < 0.5)
    elif light["type"] == "disk":
        assert np.all(p[:, 1] == 1.5) and np.all(np.hypot(p[:, 0], p[:, 2]) < 0.5)
    else:
        np.testing.assert_allclose(np.linalg.norm(p - [0.0, 1.5, 0.0], axis=1), 0.3, rtol=1e-15)
        np.testing.assert_allclose(rows.axis, (p - [0.0, 1.5, 0.0]) / 0.3, rtol=0, atol=1e-15)


@pytest.mark.parametrize("light", [QUAD, DISK, SPHERE])
@pytest.mark.parametrize("two_sided", [False, True])
def test_emitted_power_is_pi_l_a_per_side(light, two_sided):
    """scipy over the sphere of directions: sum over rows of I_i max(0, n_i·u) dw = pi L A (x 2)."""
    if two_sided and light["type"] == "sphere":
        pytest.skip("a sphere emits outward only")
    lt, rows = _rows(light, 1 if light["type"] == "sphere" else 3, two_sided)
    # every row's kink max(0, n·u) = 0 on a piece's edge: theta = pi/2 (planar, normals +-y), phi = 0, pi
    # (the sphere's rule of order 1: normals +-z)

    def intensity(theta, phi):
        u = np.array([math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi)])
        return float(np.sum(rows.intensity[:, 0] * np.maximum(rows.axis @ u, 0.0))) * math.sin(theta)

    got = sum(integrate.dblquad(intensity, p0, p0 + math.pi, t0, t0 + math.pi / 2, epsabs=0, epsrel=1e-11)[0]
              for p0 in (0.0, math.pi) for t0 in (0.0, math.pi / 2))
    want = math.pi * 10.0 * AREAS[light["type"]](lt) * (2 if two_sided else 1)
    assert abs(got - want) <= 1e-10 * want, (got, want)
    assert abs(power_of(lt)[0] - want) <= 1e-13 * want


def test_lambert_falloff_and_its_band():
    """F = max(c, 0); the band as analytic's trigonometric polynomial, F = A sin(phi) - B cos(phi)."""
    for c in np.linspace(-1.0, 1.0, 41):
        assert falloff(c, 0.0, 1.0, LAMBERT) == max(c, 0.0)
    rng = np.random.default_rng(7)
    for _ in range(20):
        a, b = np.zeros(4), np.zeros(4)
        ax = rng.normal(size=3)
        A, B = ax[:2] / np.linalg.norm(ax)
        band_trig(A, B, 0.0, 1.0, LAMBERT, a, b)
        for phi in rng.uniform(0.0, math.pi, 5):
            series = sum(a[m] * math.cos(m * phi) + b[m] * math.sin(m * phi) for m in range(4))
            assert abs(series - (A * math.sin(phi) - B * math.cos(phi))) <= 1e-15


def test_rows_name_their_scene_light():
    lights = Lights.of(scene([{"position": [0.0, 2.0, 0.0], "intensity": 1.0}, QUAD, SPHERE]).lights)
    n_quad, n_sphere = quad.ORDER ** 2, 2 * sphere.ORDER ** 2
    assert lights.owner.tolist() == [0] + [1] * n_quad + [2] * n_sphere
    assert lights.cubature.tolist() == [False] + [True] * (n_quad + n_sphere)
    assert lights.kinds() == {"point", "quad", "sphere", "spot"}


VACUUM = {"sigma_a": 0.0, "sigma_s": 0.0}
LOOK_UP = {"position": [0.0, 0.0, 0.0], "look_at": [0.0, 1.0, 0.0], "up": [0.0, 0.0, 1.0], "fov": 10.0,
           "width": 3, "height": 3}


@pytest.mark.parametrize("two_sided", [False, True])
def test_the_camera_sees_the_front_and_a_black_back(two_sided):
    """In a vacuum the camera looking up at the quad (facing down) sees its radiance exactly; from
    above, its back: black, or the radiance when two-sided. With fog: L e^{-kt d} plus the air-light."""
    light = {**QUAD, "two_sided": two_sided}
    below = api.render(scene([light], VACUUM, LOOK_UP), "quadrature").array
    np.testing.assert_array_equal(below, 10.0)
    above = api.render(scene([light], VACUUM, {**LOOK_UP, "position": [0.0, 3.0, 0.0], "look_at": [0.0, 0.0, 0.0]}),
                       "quadrature").array
    np.testing.assert_array_equal(above, 10.0 if two_sided else 0.0)
    fog = api.render(scene([QUAD], FOG, LOOK_UP), "quadrature", volumetric_shadows=False)
    assert np.all(fog.array > 10.0 * math.exp(-KT * 1.5)) and np.all(fog.array < 10.0)


def test_the_emitter_shadows_a_light_behind_it():
    """A point light above the quad light (facing down): the floor below gets nothing from it in the
    quad's shadow, and the quad's own light is not shadowed by its own triangles (the floor under it
    is as bright with the point light switched off as the quad alone renders it)."""
    floor = {"primitive": "quad", "corners": [[-3.0, -1.0, 3.0], [3.0, -1.0, 3.0], [3.0, -1.0, -3.0],
                                               [-3.0, -1.0, -3.0]], "reflectance": 0.5}
    cam = {"position": [0.0, 1.0, 0.0], "look_at": [0.0, -1.0, 0.0], "up": [0.0, 0.0, -1.0], "fov": 20.0,
           "width": 4, "height": 4}
    point = {"position": [0.0, 2.5, 0.0], "intensity": 100.0}
    both = api.render(scene([QUAD, point], VACUUM, cam, [floor]), "quadrature").array
    alone = api.render(scene([QUAD], VACUUM, cam, [floor]), "quadrature").array
    np.testing.assert_allclose(both, alone, rtol=1e-15, atol=0)
    # the floor's centre, 2.5 below the quad's centre, against the exact form factor of a parallel
    # rectangle seen from a point on the normal through its corner (four quarters of side 0.5)
    x = 0.5 / 2.5
    corner = 2 * x / math.sqrt(1 + x * x) * math.atan(x / math.sqrt(1 + x * x)) / (2 * math.pi)
    # (at rtol 1e-12: the pilot's order meets the method's precision, not more)
    centre = api.render(scene([QUAD], VACUUM, {**cam, "width": 1, "height": 1}, [floor]), "quadrature",
                        rtol=1e-12).array
    assert abs(centre[0, 0, 0] - 0.5 / math.pi * 10.0 * math.pi * 4 * corner) <= 1e-12 * centre[0, 0, 0]


TWINS = {"quad": (QUAD, lambda **k: twin.Quad(QUAD["corners"], 10.0, **k)),
         "two-sided quad": ({**QUAD, "two_sided": True}, lambda **k: twin.Quad(QUAD["corners"], 10.0, two_sided=True, **k)),
         "disk": (DISK, lambda **k: twin.Disk(DISK["center"], DISK["normal"], 0.5, 10.0, **k)),
         "sphere": (SPHERE, lambda **k: twin.Sphere(SPHERE["center"], 0.3, 10.0))}
SMALL = {**CAMERA, "width": 8, "height": 6}


def near_pixels(em, o, dirs):
    """(H, W) whether each ray passes within 1/8 of the emitter's diameter of its twin's nodes."""
    d = dirs.reshape(-1, 3)
    rel = em.y - o
    t = np.maximum(rel @ d.T, 0.0).T  # (N, nodes)
    dist = np.linalg.norm(rel[None] - t[..., None] * d[:, None, :], axis=-1).min(axis=1)
    diameter = max(np.linalg.norm(em.y - p, axis=1).max() for p in em.y[::97])
    return (dist < diameter / 8).reshape(dirs.shape[:2])


@pytest.mark.parametrize("kind", ["quad", "two-sided quad", "disk", "sphere"])
def test_unoccluded_area_light_in_fog_against_the_twin(kind):
    """An area light alone in a homogeneous isotropic fog, 8 x 6 pixels, its order chosen by the pilot:
    quadrature (rtol 1e-6, with and without volumetric shadows: the emitter does not shadow its own
    points) and analytic (precision 1e-6) within 1e-6 of the twin on every pixel whose ray passes farther
    than 1/8 of the emitter's diameter from it (the twin's composite rule, exact to rounding there),
    and the rays nearer (each by the rule about its foot point, rendering/near_emitters.py) against the
    exact twin (polar about the foot point: another rule) within 1e-6 too, reported as near and
    converged; the sphere on every pixel, each ray by the rule about its segment (tests/test_sphere_rule.py;
    all counted as near, converged). Every error bound is infinite (the cubature has none)."""
    light, make = TWINS[kind]
    em = make()
    o = np.array(SMALL["position"])
    dirs = twin.camera_rays(o, SMALL["look_at"], [0.0, 1.0, 0.0], SMALL["fov"], SMALL["width"], SMALL["height"])
    ref = np.array([[twin.radiance(em, o, d, KT, KS) for d in row] for row in dirs])
    near = near_pixels(em, o, dirs) if kind != "sphere" else np.zeros(ref.shape, dtype=bool)
    if near.any():
        exact = make(exact=True)
        ref[near] = [twin.radiance(exact, o, d, KT, KS) for d in dirs[near]]
    sc = scene([light], camera=SMALL)
    renders = (api.render(sc, "quadrature", volumetric_shadows=False, rtol=1e-6),
               api.render(sc, "quadrature", volumetric_shadows=True, rtol=1e-6),
               api.render(sc, "analytic", volumetric_shadows=False, precision=1e-6))
    for img in renders:
        rel = np.abs(img.array[..., 0] / ref - 1)
        assert np.all(np.isinf(img.error_bound))
        assert img.stats["cubature: emitters capped"] == 0, img.stats
        if kind == "sphere":  # every ray by the rule about its segment
            near = np.ones(ref.shape, dtype=bool)
        else:
            assert near.any() and not near.all() and rel[~near].max() <= 1e-6, (img.method, rel[~near].max())
        assert rel[near].max() <= 1e-6, (img.method, rel[near].max())
        assert img.stats["cubature: rays near an emitter"] == near.sum(), img.stats
        assert img.stats["cubature: rays near an emitter not converged"] == 0, img.stats


@pytest.mark.parametrize("light", [QUAD, SPHERE])
def test_raymarch_and_montecarlo_integrate_the_same_rows(light, monkeypatch):
    """The stochastic and marched methods see the same emitter points: montecarlo (64 samples per row)
    is unbiased against quadrature's value of the rows (mean squared z-score of the 48 pixels below 2,
    no pixel beyond 5 sigma); raymarch with 4096 midpoint steps per segment within 1e-3 of it (its
    midpoint rule); both leave the emitter's own radiance as it is and refuse no area light. (The
    pilot, which chooses quadrature's order, narrowed to the kinds' ORDER, the rows of the others.)"""
    monkeypatch.setattr(cubature, "AREA_LADDER", (quad.ORDER,))
    assert quad.ORDER == sphere.ORDER
    sc = scene([light], camera=SMALL)
    ref = api.render(sc, "quadrature", volumetric_shadows=True, rtol=1e-10).array
    mc = api.render(sc, "montecarlo", volumetric_shadows=True, samples=64, seed=3)
    z = (mc.array - ref) / np.sqrt(mc.variance)
    assert np.mean(z**2) < 2.0 and np.abs(z).max() < 5.0, (np.mean(z**2), np.abs(z).max())
    rm = api.render(sc, "raymarch", volumetric_shadows=True, steps=4096).array
    assert np.abs(rm / ref - 1).max() < 1e-3


EMISSIVE_QUAD = {"primitive": "quad", "corners": QUAD["corners"], "emission": 10.0}


def test_the_triangle_rule_is_exact_to_degree_5():
    """The emissive triangles' 7-point rule against scipy on a triangle, for every monomial x^a y^b, a + b <= 5."""
    from raytrace.lights import emissive

    tri = np.array([[0.2, -0.1, 0.0], [1.3, 0.4, 0.0], [0.1, 0.9, 0.0]])
    nodes = emissive.BARY @ tri
    area = 0.5 * abs(np.cross(tri[1] - tri[0], tri[2] - tri[0])[2])
    for a in range(6):
        for b in range(6 - a):
            def f(t, s):  # (s, t) barycentric over the reference triangle, Jacobian 2 area
                p = tri[0] + s * (tri[1] - tri[0]) + t * (tri[2] - tri[0])
                return p[0] ** a * p[1] ** b * 2 * area
            want = integrate.dblquad(f, 0, 1, 0, lambda s: 1 - s, epsabs=0, epsrel=1e-13)[0]
            got = area * np.sum(emissive.WEIGHTS * nodes[:, 0] ** a * nodes[:, 1] ** b)
            assert abs(got - want) <= 1e-13 * max(1.0, abs(want)), (a, b, got, want)


def test_an_emissive_shape_is_an_area_light(monkeypatch):
    """`emission` on a [[shape]]: its triangles' rows weigh its area, face its winding, name the shape after
    the lights; the camera sees it; it lights the fog as the quad light of the same corners does (within
    the cubature's error: 14 rows against 64; the pixel whose ray grazes the edge differs by 5 %), and is
    refused above MAX_TRIANGLES and by methods without spot lights."""
    from raytrace.lights import emissive
    from raytrace.rendering.renderer import prepare

    prep = prepare(scene([{"position": [0.0, 3.0, 0.0], "intensity": 1.0}], shapes=[EMISSIVE_QUAD]))
    lights = prep.lights
    assert len(lights) == 1 + 14 and lights.owner.tolist() == [0] + [1] * 14
    assert lights.kinds() == {"point", "spot", "emission"} and lights.cubature.sum() == 14
    assert abs(lights.intensity[1:, 0].sum() - 10.0) <= 1e-13 * 10.0
    np.testing.assert_array_equal(lights.axis[1:], np.tile([0.0, -1.0, 0.0], (14, 1)))
    below = api.render(scene([], VACUUM, LOOK_UP, [EMISSIVE_QUAD]), "quadrature").array
    np.testing.assert_array_equal(below, 10.0)
    shape = api.render(scene([], camera=SMALL, shapes=[EMISSIVE_QUAD]), "analytic", volumetric_shadows=True).array
    light = api.render(scene([QUAD], camera=SMALL), "analytic", volumetric_shadows=True).array
    rel = np.abs(shape / light - 1)
    assert np.median(rel) < 1e-5 and rel.max() < 0.1, (np.median(rel), rel.max())  # max: the ray by its edge
    many = {"primitive": "sphere", "center": [0.0, 1.0, 0.0], "radius": 0.2, "emission": 1.0}
    prepare(scene([], shapes=[many]))  # more than 64 triangles: grouped (tests/test_emissive_groups.py)
    monkeypatch.setattr(emissive, "MAX_TRIANGLES", 64)
    with pytest.raises(raytrace_errors.UserError, match=r"^scene: shape\[0\].emission: the shape has \d+ "
                                                        r"triangles; emissive shapes of more than 64 are not "
                                                        r"read; use a coarser mesh"):
        prepare(scene([], shapes=[many]))


@pytest.mark.parametrize("shape,message", [
    ({**EMISSIVE_QUAD, "emission": -1.0}, "shape[0].emission: must be >= 0.0"),
    ({**EMISSIVE_QUAD, "two_sided": "yes"}, "shape[0].two_sided: expected true or false"),
    ({"primitive": "quad", "corners": QUAD["corners"], "two_sided": True}, "shape[0].two_sided: is read only with "
                                                                            "emission"),
    ({"primitive": "box", "min": [-1.0, -1.0, -1.0], "max": [1.0, 0.0, 1.0], "interior": {"sigma_s": 0.1},
      "emission": 1.0}, "shape[0].emission: a shape that holds a medium cannot emit yet"),
])
def test_bad_emission_is_one_line(write_scene, tmp_path, capsys, shape, message):
    path = write_scene({"camera": CAMERA, "shape": [shape], "medium": FOG})
    assert main(["render", str(path), "--out", str(tmp_path / "x.exr"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and message in err, err


def test_methods_without_spot_lights_refuse_emissive_shapes(write_scene, tmp_path, capsys):
    path = write_scene({"camera": CAMERA, "shape": [EMISSIVE_QUAD], "medium": FOG})
    assert main(["render", str(path), "--out", str(tmp_path / "x.exr"), "--quiet", "--method", "lecocq"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--method lecocq: it does not take emissive shapes (shape.emission); use --method analytic" in err, err
