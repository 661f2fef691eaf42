"""The exact sphere (`primitive = "sphere"`, `exact = true`; raytrace/geometry/sphere.py, geometry/accel.py).

Its float64 roots against 50-digit mpmath roots of the same float64 inputs (grazing rays, rays from
inside, huge and tiny radii, far centres), within the rounding of the stable form (module docstring);
hits merged with Embree's triangles (nearest wins, occlusion by either); a rendered sphere under a
point light against Lambert's law at the pixel centres (an independent numpy twin); the refusals.
"""
import math

import mpmath
import numpy as np
import pytest

from raytrace.errors import UserError
from raytrace.geometry.accel import Accelerator
from raytrace.geometry.sphere import sphere_roots
from raytrace.interiors import crossing, shapes
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text
from raytrace.scene.meshes import quad_triangles, sphere_triangles

from . import oracle
from .conftest import to_toml

EPS = np.finfo(float).eps
mpmath.mp.dps = 50


def mp_roots(o, d, c, r):
    """The roots of |o + t d - c| = r from the float64 inputs, in 50 digits (None on a miss)."""
    f = [mpmath.mpf(float(a)) - mpmath.mpf(float(b)) for a, b in zip(o, c)]
    dd = [mpmath.mpf(float(x)) for x in d]
    a = sum(x * x for x in dd)
    b = sum(x * y for x, y in zip(f, dd))
    cc = sum(x * x for x in f) - mpmath.mpf(float(r)) ** 2
    disc = b * b - a * cc
    if disc < 0:
        return None
    return (-b - mpmath.sqrt(disc)) / a, (-b + mpmath.sqrt(disc)) / a


def allowed_error(o, d, c, r, t):
    """The rounding of the stable form: 8 eps (|t| + |f|) plus the discriminant's, whose offset h of the
    line from the centre carries 8 eps |f|: sqrt(disc) moves by min(sqrt(2 r dh), r dh / sqrt(disc)).
    Evaluated in units of max(|f|_inf, r), so that it neither underflows nor overflows."""
    f = np.asarray(o, float) - c
    s = max(np.max(np.abs(f)), r)
    f, r, t = f / s, r / s, t / s
    d = np.asarray(d, float) / np.linalg.norm(d)
    h = np.linalg.norm(f - (f @ d) * d)
    dh = 8 * EPS * np.linalg.norm(f)
    disc = max((r - h) * (r + h), 0.0)
    return s * (8 * EPS * (abs(t) + np.linalg.norm(f)) + min(math.sqrt(2 * r * dh), r * dh / math.sqrt(disc) if disc
                                                          else np.inf))


def ray_cases(rng):
    """(o, d, c, r): random, grazing, from inside, near the surface, huge, tiny and far."""
    cases = []
    for scale in (1e-200, 1e-8, 1.0, 1e7, 1e200):
        for _ in range(40):
            c = rng.normal(size=3) * scale
            r = scale * rng.uniform(0.1, 3.0)
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            kind = rng.integers(4)
            if kind == 0:  # from outside, aimed near the centre
                o = c - d * r * rng.uniform(1.5, 1e6) + rng.normal(size=3) * r * 0.3
            elif kind == 1:  # grazing: the line passes within 1e-9 r of the surface
                side = np.cross(d, rng.normal(size=3))
                side /= np.linalg.norm(side)
                o = c + side * r * (1.0 - rng.uniform(0.0, 1e-9)) - d * r * rng.uniform(2.0, 1e3)
            elif kind == 2:  # from inside
                o = c + rng.normal(size=3) * r * 0.3
            else:  # from just off the surface (a shadow ray's start)
                n = rng.normal(size=3)
                o = c + n / np.linalg.norm(n) * r * (1.0 + rng.uniform(-1e-9, 1e-9))
            cases.append((o, d * rng.uniform(0.5, 2.0), c, r))
    far = rng.normal(size=3) * 1e12  # a unit sphere a trillion units from the origin
    for _ in range(40):
        d = rng.normal(size=3)
        cases.append((far - d * 1e9 + rng.normal(size=3) * 0.5, d / np.linalg.norm(d), far + 0.0, 1.0))
    return cases


def test_roots_against_mpmath():
    rng = np.random.default_rng(7)
    hits = 0
    for o, d, c, r in ray_cases(rng):
        t0, t1 = sphere_roots(o, d, c, r)
        assert not (math.isnan(t0) or math.isnan(t1))
        want = mp_roots(o, d, c, r)
        if want is None or t0 == np.inf:  # a miss on one side only at the rounding of a tangent line
            if want is not None:
                assert float(want[1] - want[0]) <= 4 * allowed_error(o, d, c, r, float(want[1])) / np.linalg.norm(d)
            continue
        hits += 1
        for got, exact in zip((t0, t1), want):
            err = abs(got - float(exact)) * np.linalg.norm(d)  # as a length
            assert err <= allowed_error(o, d, c, r, float(exact) * np.linalg.norm(d)), (o, d, c, r, got, exact)
    assert hits > 150


def test_far_and_non_grazing_rays_are_exact_to_1e15():
    """Away from tangency the root is accurate to ~1e-15 of the distance, whatever the scale."""
    rng = np.random.default_rng(3)
    for scale, offset in ((1.0, 0.0), (1e-150, 0.0), (1e150, 0.0), (1.0, 1e9)):
        for _ in range(50):
            c = rng.normal(size=3) * scale + offset
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            side = np.cross(d, rng.normal(size=3))
            o = c - d * scale * rng.uniform(3.0, 100.0) + side / np.linalg.norm(side) * rng.uniform(0.0, 0.7) * scale
            t0, t1 = sphere_roots(o, d, c, scale)
            want = mp_roots(o, d, c, scale)
            assert want is not None
            for got, exact in zip((t0, t1), want):
                assert abs(got - float(exact)) <= 2e-15 * abs(float(exact)) + 4e-15 * float(abs(want[1] - want[0]))


def test_misses_and_degenerate_directions():
    c = np.zeros(3)
    assert sphere_roots(np.array([0.0, 2.0, -5.0]), np.array([0.0, 0.0, 1.0]), c, 1.0) == (np.inf, np.inf)
    assert sphere_roots(np.array([0.0, 0.0, -5.0]), np.zeros(3), c, 1.0) == (np.inf, np.inf)
    assert sphere_roots(c, np.array([0.0, 0.0, 1.0]), c, 0.0) == (np.inf, np.inf)  # nothing (format.py: radius > 0)
    t0, t1 = sphere_roots(np.array([1.0, 0.0, -5.0]), np.array([0.0, 0.0, 1.0]), c, 1.0)  # exactly tangent
    assert abs(t0 - 5.0) <= 4 * EPS * 5.0 and abs(t1 - 5.0) <= 4 * EPS * 5.0


def accel_with_sphere(centre, radius, segments=16):
    """An accelerator over a floor quad and an exact sphere whose mesh rows follow it."""
    floor = quad_triangles([[-10, 0, -10], [10, 0, -10], [10, 0, 10], [-10, 0, 10]])
    mesh = sphere_triangles(np.asarray(centre, float), radius, segments)
    tris = np.concatenate([floor, mesh])
    of = np.concatenate([np.full(len(floor), -1), np.zeros(len(mesh), dtype=int)])
    return Accelerator(tris, None, np.array([[*centre, radius]]), of), len(floor)


def test_hits_merge_with_embree():
    accel, first = accel_with_sphere([0.0, 1.0, 0.0], 0.5)
    o = np.array([[0.0, 5.0, 0.0], [0.0, 5.0, 3.0], [0.0, 1.0, 0.0], [0.0, 1.0, -5.0]])
    d = np.array([[0.0, -1.0, 0.0], [0.0, -1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]])
    t, prim = accel.first_hit(o, d)
    assert t.tolist() == [3.5, 5.0, 0.5, 4.5]  # sphere top; floor; from the centre; the sphere's side
    assert prim.tolist() == [first, prim[1], first, first] and 0 <= prim[1] < first
    assert accel.hit_distance32(o, d)[[0, 2, 3]].tolist() == [3.5, 0.5, 4.5]
    assert accel.occluded(o, d, np.array([3.4, 10.0, 0.4, 4.6])).tolist() == [False, True, False, True]
    n = accel.hit_normals(prim, o + t[:, None] * d)
    assert np.allclose(n[[0, 2, 3]], [[0, 1, 0], [0, -1, 0], [0, 0, -1]], atol=0, rtol=0)
    alone = accel.subset("sphere", lambda: np.arange(first, len(accel.triangles)))
    ts, ps = alone.first_hit(o, d)
    assert ts[1] == np.inf and ps[1] == -1 and ts[0] == 3.5 and alone.ids[ps[0]] == first
    floor = accel.subset("floor", lambda: np.arange(first))
    assert floor.first_hit(o[:1], d[:1])[0][0] == 5.0 and not floor.occluded(o[3:], d[3:], np.array([9.0]))[0]


SCENE = {
    "camera": {"position": [0.3, 1.2, 5.0], "look_at": [0.0, 1.0, 0.0], "fov": 35.0, "width": 40, "height": 30},
    "shape": [{"primitive": "sphere", "center": [0.1, 1.0, -0.2], "radius": 0.9, "exact": True, "segments": 8,
               "reflectance": [0.8, 0.5, 0.25]}],
    "light": [{"position": [2.0, 3.0, 2.5], "intensity": [40.0, 30.0, 20.0]}],
}


def lambert_twin(scene):
    """Each pixel centre's radiance: the sphere's Lambertian term, rho / pi I cos / d^2 (numpy)."""
    s = scene["shape"][0]
    c, r = np.array(s["center"]), s["radius"]
    lp, inten = np.array(scene["light"][0]["position"]), np.array(scene["light"][0]["intensity"])
    cam = scene["camera"]
    out, sure = np.zeros((cam["height"], cam["width"], 3)), np.ones((cam["height"], cam["width"]), bool)
    for j in range(cam["height"]):
        for i in range(cam["width"]):
            o, d = oracle.camera_ray(cam, i, j)
            b = d @ (o - c)
            disc = b * b - ((o - c) @ (o - c) - r * r)
            sure[j, i] = abs(disc) > 1e-6  # not at the silhouette
            if disc <= 0:
                continue
            p = o + (-b - math.sqrt(disc)) * d
            n = (p - c) / r
            to = lp - p
            dist = np.linalg.norm(to)
            out[j, i] = np.array(s["reflectance"]) / math.pi * inten * max(n @ to / dist, 0.0) / dist ** 2
    return out, sure


def test_image_against_lambert():
    """A coarse mesh (8 segments) would be off by far more: the image is the exact sphere's."""
    img = render(prepare(scene_from_text(to_toml(SCENE), "sphere.toml")), "analytic",
                 options=RenderOptions(threads=1)).image
    want, sure = lambert_twin(SCENE)
    assert np.count_nonzero(want[sure].any(axis=1)) > 150
    assert np.allclose(img[sure], want[sure], rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("extra, key", [
    ({"emission": [1.0, 1.0, 1.0], "two_sided": True}, "two_sided"),  # emitting: a sphere light (outward only)
    ({"transform": {"scale": [1.0, 2.0, 1.0]}}, "transform.scale"),
    ({"exact": "yes"}, "exact"),
])
def test_refusals(extra, key):
    scene = {**SCENE, "shape": [{**SCENE["shape"][0], **extra}]}
    with pytest.raises(UserError, match=rf"shape\[0\]\.{key}"):
        scene_from_text(to_toml(scene), "sphere.toml")


PBRT_SPHERES = """LookAt 0 1 6  0 1 0  0 1 0
Camera "perspective" "float fov" [ 40 ]
Film "rgb" "integer xresolution" [ 16 ] "integer yresolution" [ 12 ]
WorldBegin
LightSource "point" "point3 from" [ 2 4 2 ] "rgb I" [ 50 50 50 ]
MakeNamedMedium "inner" "string type" "homogeneous" "rgb sigma_a" [ 0.5 0.5 0.5 ] "rgb sigma_s" [ 1 1 1 ]
AttributeBegin
Material "diffuse" "rgb reflectance" [ 0.5 0.25 0.125 ]
Translate -1 1 0
Scale 2 2 2
Shape "sphere" "float radius" [ 0.25 ]
AttributeEnd
AttributeBegin
MediumInterface "inner" ""
Material "interface"
Translate 1 1 0
Shape "sphere" "float radius" [ 0.5 ]
AttributeEnd
"""


def spheres_of(raw):
    return [(s.get("exact"), s["center"], s["radius"], "interior" in s) for s in raw["shape"]]


def test_pbrt_spheres_come_in_exact_and_go_back_as_spheres(tmp_path):
    """pbrt spheres are read exact, opaque or holding a medium (its light paths inside and through it in
    closed form: media/convex_chords.py); both go out as pbrt spheres and come back the same (x mirrored
    on the way in: pbrt's LookAt is left-handed)."""
    from raytrace.io import pbrt

    src = tmp_path / "spheres.pbrt"
    src.write_text(PBRT_SPHERES)
    raw = pbrt.read_scene(src)
    assert [(e, list(c), r, i) for e, c, r, i in spheres_of(raw)] == [(True, [1.0, 1.0, 0.0], 0.5, False),
                                                                      (True, [-1.0, 1.0, 0.0], 0.5, True)]
    assert raw["shape"][1]["segments"] == pbrt.SPHERE_SEGMENTS
    out = tmp_path / "back.pbrt"
    pbrt.export(raw, out, str(src), False)
    text = out.read_text()
    assert text.count('Shape "sphere"') == 2 and "trianglemesh" not in text
    back = pbrt.read_scene(out)
    assert [(e, list(c), r, i) for e, c, r, i in spheres_of(back)] == \
        [(e, list(c), r, i) for e, c, r, i in spheres_of(raw)]
    assert back["shape"][1]["segments"] == pbrt.SPHERE_SEGMENTS


def test_pbrt_medium_sphere_round_trip_renders_the_same(tmp_path):
    """benchmarks/sphere_in_fog.toml with its sphere exact, exported to pbrt and read back: an exact sphere
    again, the same image bit for bit (it came back as a 64-segment mesh, ten times slower to render with
    volumetric shadows: docs/bounded_media.md); the same sphere as a mesh goes out as its triangles and
    comes back a mesh."""
    import tomllib
    from pathlib import Path

    from raytrace.io import pbrt

    raw = tomllib.loads((Path(__file__).parents[1] / "benchmarks" / "sphere_in_fog.toml").read_text())
    raw["camera"] |= {"width": 12, "height": 9}
    for exact in (True, False):
        raw["shape"][1]["exact"] = exact
        src = tmp_path / f"fog{exact}.toml"
        src.write_text(to_toml(raw))
        out = tmp_path / f"back{exact}.pbrt"
        pbrt.export(raw, out, str(src), False)
        back = pbrt.read_scene(out)
        assert back["shape"][1].get("primitive") == ("sphere" if exact else "triangles")
        assert ('Shape "sphere"' in out.read_text()) == exact
    images = [render(prepare(scene_from_text(to_toml(r), "fog")), "quadrature", {}, RenderOptions(threads=1)).image
              for r in ({**raw, "shape": [raw["shape"][0], raw["shape"][1] | {"exact": True}]},
                        pbrt.read_scene(tmp_path / "backTrue.pbrt"))]
    assert images[0].any() and np.array_equal(images[0], images[1])


MITSUBA_SPHERES = """<scene version="3.0.0">
<sensor type="perspective"><float name="fov" value="40"/><string name="fov_axis" value="y"/>
<transform name="to_world"><lookat origin="0, 1, 6" target="0, 1, 0" up="0, 1, 0"/></transform>
<film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="12"/></film></sensor>
<emitter type="point"><point name="position" value="2, 4, 2"/><rgb name="intensity" value="50"/></emitter>
<shape type="sphere"><point name="center" value="-1, 1, 0"/><float name="radius" value="0.5"/>
<bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.25, 0.125"/></bsdf></shape>
<medium type="homogeneous" id="inner"><rgb name="sigma_t" value="1.5"/><rgb name="albedo" value="0.5"/></medium>
<shape type="sphere"><point name="center" value="1, 1, 0"/><float name="radius" value="0.5"/>
<bsdf type="null"/><ref name="interior" id="inner"/></shape>
</scene>
"""


def test_mitsuba_spheres_come_in_exact_and_go_back_as_spheres(tmp_path):
    from raytrace.io import mitsuba

    src = tmp_path / "spheres.xml"
    src.write_text(MITSUBA_SPHERES)
    raw = mitsuba.read_scene(src)
    assert [(e, i) for e, _, _, i in spheres_of(raw)] == [(True, False), (True, True)]
    out = tmp_path / "back.xml"
    mitsuba.export(raw, out, str(src), False)
    assert out.read_text().count('<shape type="sphere"') == 2 and not list(tmp_path.glob("*.ply"))
    back = mitsuba.read_scene(out)
    for (e, c, r, i), (e2, c2, r2, i2) in zip(spheres_of(raw), spheres_of(back)):
        assert (e, i) == (e2, i2) and np.allclose(c, c2, rtol=1e-15, atol=0) and r == pytest.approx(r2, rel=1e-15)
    assert back["shape"][1]["segments"] == raw["shape"][1]["segments"] == mitsuba.INTERIOR_SEGMENTS


def blocked_twin(p, light, sun, c, r):
    """numpy: the closest point to c of the segment p -> L (sun: of the ray p + s l, s >= 0) lies within
    r, and the segment does not lie wholly inside the sphere (a light inside lights its inside)."""
    if sun:
        s = max((c - p) @ light, 0.0)
        q = p + s * light
    else:
        u = light - p
        s = min(max((c - p) @ u / (u @ u), 0.0), 1.0)
        q = p + s * u
        if np.linalg.norm(p - c) < r and np.linalg.norm(light - c) < r:
            return False
    return np.linalg.norm(q - c) <= r


def twin_breaks(o, w, length, light, sun, spheres, n=2000):
    """Where the shadow of `spheres` along o + x w changes: a grid of n samples, each change bisected."""
    def dark(x):
        return any(blocked_twin(o + x * w, light, sun, s[:3], s[3]) for s in spheres)
    xs = np.linspace(0.0, length, n)
    state = [dark(x) for x in xs]
    out = []
    for k in range(n - 1):
        if state[k] != state[k + 1]:
            a, b = xs[k], xs[k + 1]
            for _ in range(60):
                m = 0.5 * (a + b)
                a, b = (m, b) if dark(m) == state[k] else (a, m)
            out.append(0.5 * (a + b))
    return out, dark


def shadow_cases(rng):
    for _ in range(80):
        sun = bool(rng.integers(2))
        spheres = np.array([[*rng.normal(size=3) * 2.0, rng.uniform(0.3, 1.2)] for _ in range(rng.integers(1, 3))])
        if sun:
            light = rng.normal(size=3)
            light /= np.linalg.norm(light)
        else:
            light = rng.normal(size=3) * 4.0
        o = rng.normal(size=3) * 5.0
        away = -light if sun else spheres[0, :3] - light  # aimed across the first sphere's shadow
        target = spheres[0, :3] + away / np.linalg.norm(away) * rng.uniform(0.0, 3.0) + rng.normal(size=3) * 0.5
        w = (target - o) / np.linalg.norm(target - o)
        yield o, w, 15.0, light, sun, spheres


def test_sphere_shadow_breaks_against_bisection():
    """The lit parts of segments near one or two spheres under point and directional lights: every
    end point is a change of the twin's shadow test (which changes nowhere else) to 1e-9."""
    from raytrace.geometry.sphere import lit_parts

    rng = np.random.default_rng(11)
    changes = 0
    for o, w, length, light, sun, spheres in shadow_cases(rng):
        out = np.empty((4 * len(spheres) + 1, 2))
        k = lit_parts(o, w, 0.0, length, light, sun, spheres, 1e-14, out)
        ends = sorted({x for x in out[:k].ravel() if 0.0 < x < length})
        want, dark = twin_breaks(o, w, length, light, sun, spheres)
        assert len(ends) == len(want), (ends, want)
        assert np.allclose(ends, want, rtol=0, atol=1e-9)
        for a, b in out[:k]:  # the parts are lit, what lies between them dark
            assert not dark(0.5 * (a + b))
        for (_, b), (a, _) in zip(out[:k - 1], out[1:k]):
            assert dark(0.5 * (a + b))
        changes += len(want)
    assert changes > 100


def test_light_inside_and_grazing_shadow_edges():
    from raytrace.geometry.sphere import lit_parts

    out = np.empty((5, 2))
    sphere = np.array([[0.0, 0.0, 0.0, 1.0]])
    o, w = np.array([-5.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])
    k = lit_parts(o, w, 0.0, 10.0, np.array([0.2, 0.1, 0.0]), False, sphere, 1e-14, out)  # light inside
    assert k == 1 and np.allclose(out[0], [4.0, 6.0], rtol=0, atol=1e-15)
    # a directional light straight down, a segment along x at height -1 below the sphere: dark on [-1, 1]
    k = lit_parts(np.array([-5.0, -2.0, 0.0]), w, 0.0, 10.0, np.array([0.0, 1.0, 0.0]), True, sphere, 1e-14, out)
    assert k == 2 and np.allclose(out[:2], [[0.0, 4.0], [6.0, 10.0]], rtol=0, atol=1e-15)


def test_frusta_take_exact_sphere_occluders():
    """exact_lit_intervals in a scene with a floor and an exact sphere: the pieces of camera-ray
    segments are the twin's lit sets (the sphere shadows as a sphere, not as its 8-segment mesh)."""
    from raytrace.segments import whole_rays
    from raytrace.shadows.frusta import exact_lit_intervals

    scene = {**SCENE, "shape": [{**SCENE["shape"][0]},
                                {"primitive": "quad", "corners": [[-9, -0.5, -9], [9, -0.5, -9], [9, -0.5, 9],
                                                                  [-9, -0.5, 9]]}],
             "medium": {"sigma_a": 0.01, "sigma_s": 0.05}}
    prep = prepare(scene_from_text(to_toml(scene), "sphere.toml"))
    s = scene["shape"][0]
    sphere = np.array([[*s["center"], s["radius"]]])
    light = np.array(scene["light"][0]["position"], float)
    rng = np.random.default_rng(5)
    o = np.array([[0.3, 1.2, 5.0]] * 40)
    d = np.array([0.0, -0.3, -1.0]) + rng.normal(size=(40, 3)) * 0.25
    d /= np.linalg.norm(d, axis=1)[:, None]
    t, _ = prep.accel.first_hit(o, d)
    segs = whole_rays(o, d, np.minimum(t, 12.0), np.arange(40), 1)
    pieces, _ = exact_lit_intervals(prep.accel, segs, prep.lights, 1, prep.frusta())
    total = 0
    for i in range(40):
        mine = pieces.ray == i
        ends = sorted({x for a, b in zip(pieces.t0[mine], pieces.t0[mine] + pieces.length[mine]) for x in (a, b)
                       if 1e-9 < x < segs.length[i] - 1e-9})
        want, _ = twin_breaks(o[i], d[i], segs.length[i], light, False, sphere)
        want = [x for x in want if 1e-9 < x < segs.length[i] - 1e-9]
        assert len(ends) == len(want) and np.allclose(ends, want, rtol=0, atol=1e-9), (i, ends, want)
        total += len(want)
    assert total > 10


FOG_SPHERE_LIGHTS = {"point": None,  # test_interiors_scale.SPHERE's own
                     "spot": {"type": "spot", "position": [2.0, 2.0, 1.0], "look_at": [0.1, -0.2, 0.0],
                              "cone_angle": 20.0, "falloff_start": 12.0, "intensity": 5.0},
                     "directional": {"type": "directional", "direction": [-0.5, -1.0, -0.3], "irradiance": 2.0}}


@pytest.mark.parametrize("light", FOG_SPHERE_LIGHTS)
def test_fog_sphere_against_the_exact_twin(light):
    """tests/test_interiors_scale.py's sphere of fog under a point light, a spot whose cone edges cross
    it, and a directional light (in a vacuum), exact: every pixel whose centre ray crosses it against the twin (scipy
    quad on the analytic chords, 1e-11) to 2e-9 with quadrature at rtol 1e-10, where its 512-segment
    mesh is off by ~1e-4 (O(1 / segments^2)); a sphere has no face planes (shapes.hull_planes): its
    light paths are the closed-form chords of media/slab.py's kernel (kind SPHERE), without facet
    kinks. Its error bound (media/slab.py sphere_rounding and the rule's) holds at every pixel and is
    not vacuous: median at most 10 rtol of the value."""
    from .test_interiors_scale import SPHERE, exact_pixel, sphere_chord

    sc = {**SPHERE, "shape": [SPHERE["shape"][0] | {"exact": True}]}
    if FOG_SPHERE_LIGHTS[light] is not None:
        sc["light"] = [FOG_SPHERE_LIGHTS[light]]
    if light == "directional":  # the sun reaches the sphere through a vacuum (scene/format.py)
        sc["medium"] = {"sigma_a": 0.0}
    prep = prepare(scene_from_text(to_toml(sc), "sphere"))
    result = render(prep, "quadrature", {"rtol": 1e-10}, RenderOptions(threads=1))
    img, bound = result.image, result.error_bound
    assert shapes.hull_planes(prep, 0) is None
    worst, n, ratios = 0.0, 0, []
    for j in range(sc["camera"]["height"]):
        for i in range(sc["camera"]["width"]):
            chord = sphere_chord(*oracle.camera_ray(sc["camera"], i, j))
            if chord is not None and chord[1] - chord[0] > 1e-3:
                ref = exact_pixel(sc, i, j)
                lit = ref > 0.0
                worst = max(worst, float(np.max(np.abs(img[j, i] - ref)[lit] / ref[lit], initial=0.0)))
                assert np.all(np.abs(img[j, i] - ref) <= bound[j, i] + 1e-12 * ref), (i, j, img[j, i], ref, bound[j, i])
                ratios += list(bound[j, i][lit] / ref[lit])
                n += 1
            elif chord is None:
                assert not img[j, i].any()
    assert n > 30 and worst < 2e-9, (n, worst)
    assert np.all(np.isfinite(ratios)) and np.median(ratios) <= 10 * 1e-10, np.median(ratios)


@pytest.mark.parametrize("method, params", [("raymarch", {"steps": 4000}), ("montecarlo", {"samples": 4000}),
                                            ("analytic", {})])
def test_every_method_takes_the_exact_sphere_in_its_kernel(monkeypatch, method, params):
    """raymarch, montecarlo and analytic (directional light: its hand-over to quadrature, counted and
    bounded) inside the exact fog sphere, with volumetric shadows, without one Embree walk (paths.walk
    refuses): against the twin of `test_fog_sphere_against_the_exact_twin` to the midpoint rule's 1e-6
    at 4000 steps, 5 standard errors, and analytic's bound."""
    from raytrace.interiors import paths

    from .test_interiors_scale import SPHERE, exact_pixel

    monkeypatch.setattr(paths, "walk", lambda *a, **k: pytest.fail("an Embree walk inside an exact sphere"))
    sc = {**SPHERE, "shape": [SPHERE["shape"][0] | {"exact": True}]}
    if method == "analytic":
        sc["light"], sc["medium"] = [FOG_SPHERE_LIGHTS["directional"]], {"sigma_a": 0.0}
    prep = prepare(scene_from_text(to_toml(sc), "sphere"))
    result = render(prep, method, params, RenderOptions(threads=1, volumetric_shadows=True))
    checked = 0
    for j, i in [(4, 6), (3, 5), (5, 7), (2, 6)]:
        ref = exact_pixel(sc, i, j)
        got = result.image[j, i]
        if method == "montecarlo":
            assert np.all(np.abs(got - ref) <= 5.0 * np.sqrt(result.variance[j, i])), (got, ref)
        elif method == "raymarch":
            assert np.max(np.abs(got - ref) / ref) < 1e-6, (got, ref)
        else:
            assert np.all(np.abs(got - ref) <= result.error_bound[j, i] + 1e-12 * ref), (got, ref)
            assert np.max(result.error_bound[j, i] / ref) < 1e-8
        checked += 1
    assert checked == 4
    if method == "analytic":
        assert result.stats["inside: segments handed to quadrature"] > 0


@pytest.mark.slow  # about 1.5 min: a study of the meshes' convergence (each kind verified by its own twin)
def test_refractive_sphere_meshes_approach_the_exact_sphere():
    """A refractive sphere of fog (ior 1.33) under a point light: meshes of 16 and 32 segments (128 and
    512 face planes, more than media/slab.py's convex kernel takes) are lit through every face the
    light is outside of, on Fermat's path through each (shapes.refracting_planes, rows REFRACTED;
    verified against a twin in tests/test_refracted_mesh_faces.py), so that their images approach
    the exact sphere's (rows REFRACTED too: its exact refracted paths, media/sphere_refraction.py,
    verified in tests/test_refracted_sphere.py) as the mesh is refined: median relative difference
    over the channels lit in all three 9.6 % at 16 segments, 5.8 % at 32 (4.0 % at 64, not rendered
    here: it takes half a minute), where the former entry-plane model of meshes was more than 20 % off."""
    from .test_interiors_scale import SPHERE

    images = {}
    for name, extra in (("exact", {"exact": True}), ("16", {"segments": 16}), ("32", {"segments": 32})):
        inner = SPHERE["shape"][0]["interior"] | {"ior": 1.33}
        prep = prepare(scene_from_text(to_toml({**SPHERE, "shape": [SPHERE["shape"][0] | extra | {"interior": inner}]}),
                                       name))
        assert not len(shapes.convex_planes(prep, 0))
        faces = len(shapes.refracting_planes(prep, 0))
        assert faces == 0 if name == "exact" else faces > shapes.KERNEL_PLANES, faces
        rows = crossing._rows(prep, 0, np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, -1.0]]),
                              np.ones(1), np.zeros(1, np.uint64))
        assert rows.reach[0] == crossing.REFRACTED
        images[name] = render(prep, "quadrature", {}, RenderOptions(threads=1)).image
    ref = images["exact"]
    lit = (ref > 0.0) & (images["16"] > 0.0) & (images["32"] > 0.0)
    off = {k: float(np.median(np.abs(images[k] - ref)[lit] / ref[lit])) for k in ("16", "32")}
    assert lit.sum() > 60 and off["32"] < 0.07 and off["32"] < 0.7 * off["16"], off


def test_camera_inside_the_exact_fog_sphere():
    """The camera at (0.2, 0.1, 0.3) inside the exact sphere of fog (crossing.start_inside): each pixel
    centre's integral over [0, exit] against the twin on the analytic chords to 2e-9."""
    from scipy import integrate

    from .test_interiors_scale import SPHERE, sphere_chord

    cam = {**SPHERE["camera"], "position": [0.2, 0.1, 0.3], "look_at": [0.0, -0.2, -1.0]}
    sc = {**SPHERE, "camera": cam, "shape": [SPHERE["shape"][0] | {"exact": True}]}
    prep = prepare(scene_from_text(to_toml(sc), "sphere"))
    assert prep.camera_inside == 0
    img = render(prep, "quadrature", {"rtol": 1e-10}, RenderOptions(threads=1)).image
    inner = sc["shape"][0]["interior"]
    ks = np.array(inner["sigma_s"])
    kt = np.array(inner["sigma_a"]) + ks
    lp = np.array(sc["light"][0]["position"], float)
    kt_out = sc["medium"]["sigma_a"]
    worst = 0.0
    for j, i in [(0, 0), (3, 5), (7, 11), (4, 2)]:
        o, d = oracle.camera_ray(cam, i, j)

        def radiance(t):  # all three channels at once: ks Phi exp(-kt (t + k) - kt_out (dist - k)) / dist^2
            to = lp - (o + t * d)
            dist = np.linalg.norm(to)
            k = sphere_chord(o + t * d, to / dist)[1]
            phase = oracle.phase("hg", inner["phase"]["g"], float(to @ d) / dist)
            return ks * phase * np.exp(-kt * (t + k) - kt_out * (dist - k)) / dist**2

        ref = sc["light"][0]["intensity"] * integrate.quad_vec(radiance, 0.0, sphere_chord(o, d)[1], epsabs=0.0,
                                                               epsrel=1e-11, limit=200)[0]
        worst = max(worst, float(np.max(np.abs(img[j, i] - ref) / ref)))
    assert worst < 2e-9, worst


FOG_SHADOW = {"camera": {"position": [0.0, 0.3, 4.0], "look_at": [0.0, -0.3, 0.0], "fov": 50.0, "width": 16,
                         "height": 12, "spp": 1},
              "medium": {"sigma_a": 0.01, "sigma_s": 0.05},
              "shape": [{"primitive": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "exact": True,
                         "interior": {"sigma_a": 0.5, "sigma_s": 1.0}}],
              "light": [{"type": "point", "position": [0.4, 3.0, -1.5], "intensity": 50.0}]}


def fog_shadow_twin(o, d, light, kt, ks, dk):
    """∫_0^inf of the fog's single scattering (isotropic) along o + x d from the point light through the
    unit sphere at the origin: ks / 4 pi I exp(-kt (x + dist) - dk chord) / dist^2, the chord of the
    path to the light from the sphere's analytic roots; scipy quad cut where that path turns tangent
    to the sphere (its offset from the centre crosses 1: bracketed on a grid, brentq)."""
    from scipy import integrate, optimize

    from .test_interiors_scale import sphere_chord

    def offset(x):
        p = o + x * d
        u = (light - p) / np.linalg.norm(light - p)
        return float(np.linalg.norm(p - (p @ u) * u)) - 1.0

    def f(x):
        p = o + x * d
        dist = float(np.linalg.norm(light - p))
        u = (light - p) / dist
        c = sphere_chord(p, u)
        chord = 0.0 if c is None else max(min(c[1], dist) - max(c[0], 0.0), 0.0)
        return ks / (4 * math.pi) * math.exp(-kt * (x + dist) - dk * chord) / dist**2

    xs = np.linspace(0.0, 60.0, 1201)
    v = np.array([offset(x) for x in xs])
    cuts = [optimize.brentq(offset, xs[k], xs[k + 1], xtol=1e-15, rtol=1e-15)
            for k in np.nonzero(np.sign(v[:-1]) != np.sign(v[1:]))[0]]
    edges = [0.0, *cuts, 60.0]
    total = sum(integrate.quad(f, a, b, epsabs=0.0, epsrel=1e-12, limit=400)[0] for a, b in zip(edges, edges[1:]))
    return total + integrate.quad(f, 60.0, np.inf, epsabs=0.0, epsrel=1e-12, limit=400)[0], cuts


def test_light_through_the_exact_sphere_onto_the_fog(monkeypatch):
    """The outside fog's single scattering where the light crosses the exact sphere of denser fog (the
    pieces behind it: media/convex_chords.py through_pieces, chords in closed form, its square-root kinks
    on the light's tangent cone integrated in u = sqrt(x - x_b)): the pixels whose centre ray misses
    the sphere and crosses its shadow cone against `fog_shadow_twin` to 2e-9 at rtol 1e-10, every
    integral converged; montecarlo (its points attenuated by the closed-form chords, no Embree walk:
    paths.walk refuses) within 5 standard errors."""
    from raytrace.interiors import paths

    from .test_interiors_scale import sphere_chord

    monkeypatch.setattr(paths, "walk", lambda *a, **k: pytest.fail("an Embree walk through an exact sphere"))
    prep = prepare(scene_from_text(to_toml(FOG_SHADOW), "fog shadow"))
    result = render(prep, "quadrature", {"rtol": 1e-10}, RenderOptions(threads=1, volumetric_shadows=True))
    mc = render(prep, "montecarlo", {"samples": 256}, RenderOptions(threads=1, volumetric_shadows=True))
    assert mc.stats["shadows: pieces through interiors (montecarlo)"] > 0
    assert np.all(np.abs(mc.image - result.image) <= 5.0 * np.sqrt(mc.variance))
    assert result.stats["shadows: through-interior integrals not converged"] == 0
    assert result.stats["shadows: pieces through interiors (quadrature)"] > 0
    light = np.array(FOG_SHADOW["light"][0]["position"])
    kt, ks = 0.06, 0.05
    worst, crossing = 0.0, 0
    for j in range(FOG_SHADOW["camera"]["height"]):
        for i in range(FOG_SHADOW["camera"]["width"]):
            o, d = oracle.camera_ray(FOG_SHADOW["camera"], i, j)
            if sphere_chord(o, d) is not None:
                continue
            ref, cuts = fog_shadow_twin(o, d, light, kt, ks, 1.5 - kt)
            ref *= FOG_SHADOW["light"][0]["intensity"]
            crossing += len(cuts) > 0
            worst = max(worst, float(np.max(np.abs(result.image[j, i] - ref)) / ref))
    assert crossing > 20 and worst < 2e-9, (crossing, worst)
