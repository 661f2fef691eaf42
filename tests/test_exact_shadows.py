"""Exact lit intervals (raytrace/shadows/frusta.py) against independent twins (tests/oracle_shadows.py:
closed-form shadow boundaries of axis-aligned plates and boxes, slab tests, scipy air-light) with
occluders far thinner than the sampled search's default spacing (0.01 rad seen from the light)."""
import math

import numpy as np
import pytest

import raytrace
from raytrace.camera import generate_rays
from raytrace.geometry.accel import Accelerator
from raytrace.lights import DIRECTIONAL, Light, Lights
from raytrace.methods import get_method, resolve_params
from raytrace.rendering.renderer import prepare
from raytrace.segments import cone_segments, segment_airlight, whole_rays
from raytrace.shadows.frusta import ST_FRUSTA, ST_NEAR, ST_RUNS, build, default_resolution, exact_lit_intervals

from . import oracle, oracle_shadows

LIGHT = [0.0, 1.5, -1.0]
ROOM = ((-3.0, -2.0, -4.0), (3.0, 2.0, 4.0))
# each occluder well below 0.01 rad seen from the light, as (min, max) corners (equal y: a plate)
SLIT = [((-2.5, 0.5, -3.0), (-0.003, 0.5, 1.0)), ((0.003, 0.5, -3.0), (2.5, 0.5, 1.0))]  # 6 mm, 1 m below: 0.006 rad
WIRE = [((-0.001, 0.499, -3.0), (0.001, 0.501, 1.0))]  # 2 mm thick, 1 m below: 0.002 rad
BARS = [((x - 0.002, 0.798, -3.0), (x + 0.002, 0.802, 1.0)) for x in np.arange(-0.15, 0.151, 0.05)]  # 4 mm, 0.7 m
OCCLUDERS = {"slit": SLIT, "wire": WIRE, "bars": BARS}
CAMERA = {"position": [2.5, -1.0, 3.0], "look_at": [0.0, 0.0, -1.0], "fov": 80.0, "width": 12, "height": 9, "spp": 1}
MEDIUM = {"sigma_a": 0.05, "sigma_s": [0.2, 0.3, 0.5], "phase": {"type": "hg", "g": 0.5}}
SPOT = {"type": "spot", "position": LIGHT, "look_at": [0.3, 0.0, -1.2], "cone_angle": 40.0, "falloff_start": 30.0,
        "intensity": 20.0}
FOG = {"type": "height_fog", "sigma_a": 0.05, "sigma_s": [0.2, 0.3, 0.5], "h0": 0.0, "scale_height": 1.5,
       "phase": "isotropic"}
SUN = {"type": "directional", "direction": [0.3, -1.0, -0.2], "irradiance": 5.0}
GROUND = ((-20.0, -2.0, -20.0), (20.0, -2.0, 20.0))


def shape(box):
    lo, hi = box
    if lo[1] == hi[1]:
        y = lo[1]
        return {"primitive": "quad", "reflectance": 0.0,
                "corners": [[lo[0], y, lo[2]], [hi[0], y, lo[2]], [hi[0], y, hi[2]], [lo[0], y, hi[2]]]}
    return {"primitive": "box", "min": list(lo), "max": list(hi), "reflectance": 0.0}


def room_scene(boxes, light=None, camera=CAMERA):
    """Black walls and occluders: the image is the air-light alone."""
    return {"camera": dict(camera), "shape": [shape(ROOM) | {"reflectance": 0.0}] + [shape(b) for b in boxes],
            "light": [light or {"position": LIGHT, "intensity": 20.0}], "medium": MEDIUM}


def sun_scene(boxes):
    """Occluders over a black ground in a height fog, lit by the sun; rays that miss go to infinity."""
    cam = dict(CAMERA, position=[2.5, -0.5, 3.0])
    return {"camera": cam, "shape": [shape(GROUND)] + [shape(b) for b in boxes], "light": [SUN], "medium": FOG}


def segments(scene):
    """The prepared scene, its camera rays' segments (cut to spot cones) and the rays."""
    sc = raytrace.load(scene)
    prep = prepare(sc)
    o, d = generate_rays(sc.camera)
    t, _ = prep.accel.first_hit(o, d)
    segs = whole_rays(o, d, t, np.arange(len(o), dtype=np.uint64), len(prep.lights), 0, prep.accel.scale)
    segs, _ = cone_segments(segs, prep.lights)
    return prep, segs, (o, d, t)


def pieces_of(segs, lit, s):
    """The lit pieces (x0, x1) of segment s, relative to its start."""
    mine = (lit.ray == segs.ray[s]) & (lit.t0 >= segs.t0[s]) & (lit.t0 <= segs.t0[s] + segs.length[s])
    x0 = lit.t0[mine] - segs.t0[s]
    return list(zip(x0, x0 + lit.length[mine]))


def assert_same_pieces(mine, twin, tol):
    """Equal lists of pieces, ends within tol (pieces shorter than tol, left by rounding where a
    boundary meets the segment's end, are dropped from both)."""
    mine = [p for p in mine if p[1] - p[0] > tol]
    twin = [p for p in twin if p[1] - p[0] > tol]
    assert len(mine) == len(twin), (mine, twin)
    for (a, b), (c, e) in zip(mine, twin):
        assert abs(a - c) <= tol and (b == e or abs(b - e) <= tol), (mine, twin)


def check_intervals(scene, boxes, light, sun=False):
    prep, segs, _ = segments(scene)
    lit, stats = exact_lit_intervals(prep.accel, segs, prep.lights, 1)
    tol = 1e-12 * prep.accel.scale
    shadowed = 0
    for s in range(len(segs)):
        twin = oracle_shadows.lit_pieces(segs.origins[s], segs.dirs[s], segs.length[s], light, boxes, sun)
        assert_same_pieces(pieces_of(segs, lit, s), twin, tol)
        shadowed += twin != [(0.0, segs.length[s])]
    return shadowed, stats


@pytest.mark.parametrize("name", OCCLUDERS)
def test_thin_occluders_under_a_point_light(name):
    """Every lit piece of every camera ray, ends to 1e-12 of the scene's size, against the twin's
    closed-form boundaries: no ray misses the slit's sheet of light, the wire's or a bar's shadow."""
    boxes = OCCLUDERS[name]
    shadowed, stats = check_intervals(room_scene(boxes), boxes, LIGHT)
    assert shadowed > 10
    assert stats[ST_RUNS] > 0 and stats[ST_FRUSTA] > 0


@pytest.mark.parametrize("name", OCCLUDERS)
def test_thin_occluders_under_a_spot_light(name):
    """The same after `cone_segments` has cut the rays to the spot's cone."""
    boxes = OCCLUDERS[name]
    shadowed, _ = check_intervals(room_scene(boxes, SPOT), boxes, LIGHT)
    assert shadowed > 5


@pytest.mark.parametrize("name", OCCLUDERS)
def test_thin_occluders_under_the_sun(name):
    """Directional light, orthographic grid; rays that miss everything go to infinity."""
    boxes = OCCLUDERS[name]
    travel = np.array(SUN["direction"]) / np.linalg.norm(SUN["direction"])
    shadowed, _ = check_intervals(sun_scene(boxes), boxes + [GROUND], travel, sun=True)
    assert shadowed > 5


def test_the_sampled_search_misses_what_the_exact_intervals_find():
    """The reason for this module: at its default spacing the sampled search loses the slit's sheet
    of light on some rays (benchmarks/sampled_search.py), the exact intervals do not."""
    from benchmarks.sampled_search import lit_intervals

    prep, segs, _ = segments(room_scene(SLIT))
    exact, _ = exact_lit_intervals(prep.accel, segs, prep.lights, 1)
    sampled, _ = lit_intervals(prep.accel, segs, prep.lights, 1, 0.01)
    lit_exact = np.bincount(exact.ray, exact.length, len(segs))
    lit_sampled = np.bincount(sampled.ray, sampled.length, len(segs))
    assert np.sum(lit_exact > lit_sampled + 1e-6) >= 3


def image(prep, segs, n):
    lit, _ = exact_lit_intervals(prep.accel, segs, prep.lights, len(prep.lights))
    method = get_method("quadrature")
    params = resolve_params(method, {}, "test")
    return segment_airlight(method, prep.scene.medium, prep.lights, params, lit, n)[0]


def near_an_edge(o, d, t, boxes, reach):
    """Whether the camera ray's hit lies within `reach` of an occluder's edge (float32 territory,
    where the renderer's first hit may fall on either side)."""
    if not math.isfinite(t):
        return False
    p = o + t * d
    for lo, hi in boxes:
        lo, hi = np.asarray(lo), np.asarray(hi)
        if np.all(p >= lo - reach) and np.all(p <= hi + reach):
            near = np.minimum(np.abs(p - lo), np.abs(p - hi)) <= reach
            if near.sum() >= 2:  # on a face (or a plate's plane) and near another bounding plane
                return True
    return False


def twin_image(scene, boxes, walls, pixel):
    cam = scene["camera"]
    out = np.zeros((cam["height"] * cam["width"], 3))
    edge = np.zeros(len(out), bool)
    for j in range(cam["height"]):
        for i in range(cam["width"]):
            o, d = oracle.camera_ray(cam, i, j)
            t = min(walls(o, d), oracle_shadows.first_hit(o, d, boxes))
            out[j * cam["width"] + i] = pixel(o, d, t)
            edge[j * cam["width"] + i] = near_an_edge(o, d, t, boxes, 1e-6 * 4.0)
    return out, edge


def assert_images_agree(img, ref, edge):
    scale = ref.max()
    rel = np.abs(img - ref) / np.maximum(ref, 1e-3 * scale)
    assert edge.mean() < 0.05
    assert rel[~edge].max() <= 1e-9, rel[~edge].max()


SLOW = pytest.mark.slow  # the spot twin brackets its cone on a fine grid per piece: seconds per image


@pytest.mark.parametrize("name, light", [("slit", "point"), ("wire", "point"), ("bars", "point"), ("slit", "spot"),
                                         pytest.param("wire", "spot", marks=SLOW),
                                         pytest.param("bars", "spot", marks=SLOW)])
def test_shadowed_quadrature_matches_the_twin(name, light):
    """`quadrature` (default rtol) on the exact pieces against scipy on the twin's pieces, every
    pixel within 1e-9 (pixels whose ray ends within float32 reach of an occluder's edge excepted)."""
    boxes = OCCLUDERS[name]
    scene = room_scene(boxes, SPOT if light == "spot" else None)
    prep, segs, (o, d, t) = segments(scene)
    img = image(prep, segs, len(o))
    ks = np.broadcast_to(np.array(MEDIUM["sigma_s"], float), 3)
    kt = ks + MEDIUM["sigma_a"]
    spot = oracle.spot_of(SPOT) if light == "spot" else None
    lo, hi = np.array(ROOM[0]), np.array(ROOM[1])

    def pixel(o, d, t):
        return [oracle_shadows.point_airlight(o, d, t, LIGHT, 20.0, kt[c], ks[c], "hg", 0.5, boxes, spot)
                for c in range(3)]

    ref, edge = twin_image(scene, boxes, lambda o, d: oracle.box_exit(o, d, lo, hi)[0], pixel)
    assert (ref < 0.5 * ref.max()).any() and ref.max() > 0
    assert_images_agree(img, ref, edge)


def test_shadowed_quadrature_under_the_sun_matches_the_twin():
    boxes = BARS
    scene = sun_scene(boxes)
    prep, segs, (o, d, t) = segments(scene)
    img = image(prep, segs, len(o))
    travel = np.array(SUN["direction"]) / np.linalg.norm(SUN["direction"])
    ks = np.broadcast_to(np.array(FOG["sigma_s"], float), 3)

    def pixel(o, d, t):
        return [oracle_shadows.sun_airlight(o, d, t, travel, 5.0, FOG["sigma_a"], ks[c], "isotropic", 0.0,
                                            FOG["h0"], FOG["scale_height"], boxes + [GROUND]) for c in range(3)]

    ref, edge = twin_image(scene, boxes + [GROUND], lambda o, d: math.inf, pixel)
    assert_images_agree(img, ref, edge)


# --- unit cases on hand-made triangles -----------------------------------------------------------

def box_triangles(lo, hi):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = np.array([[lo[0] if i & 1 == 0 else hi[0], lo[1] if i & 2 == 0 else hi[1], lo[2] if i & 4 == 0 else hi[2]]
                  for i in range(8)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return np.array([c[[a, b, e]] for a, b, e, f in quads] + [c[[a, e, f]] for a, b, e, f in quads])


def lights_of(kind, where):
    if kind == "sun":
        w = np.asarray(where, float)
        return Lights.of([Light(np.zeros(3), np.ones(3), DIRECTIONAL, w / np.linalg.norm(w))])
    return Lights.of([Light(np.asarray(where, float), np.ones(3))])


def raw_segments(o, d, ell):
    o, d = np.atleast_2d(np.asarray(o, float)), np.atleast_2d(np.asarray(d, float))
    d = d / np.linalg.norm(d, axis=1)[:, None]
    return whole_rays(o, d, np.broadcast_to(np.asarray(ell, float), len(o)), np.arange(len(o), dtype=np.uint64), 1)


def test_a_segment_ending_on_a_surface_is_lit_to_its_end_only_from_the_lights_side():
    """A plate at y = 0 under a light at y = 1: a ray ending on its top is lit up to its end; a
    ray ending on its underside (the light behind the surface) is dark before it: the plate's own
    frustum decides, with no surface normal."""
    plate = np.array([[[-1.0, 0, -1], [1, 0, -1], [1, 0, 1]], [[-1.0, 0, -1], [1, 0, 1], [-1, 0, 1]]])
    accel = Accelerator(plate, np.array([[0.0, 1.0, 0.0]]))
    lights = lights_of("point", [0.0, 1.0, 0.0])
    above = raw_segments([0.3, 0.5, 2.0], [-0.3, -0.5, -2.0], math.sqrt(0.09 + 0.25 + 4.0))
    below = raw_segments([0.3, -0.5, 2.0], [-0.3, 0.5, -2.0], math.sqrt(0.09 + 0.25 + 4.0))
    a, _ = exact_lit_intervals(accel, above, lights, 1)
    b, _ = exact_lit_intervals(accel, below, lights, 1)
    assert len(a) == 1 and a.t0[0] == 0.0 and abs(a.length[0] - above.length[0]) < 1e-14
    twin = oracle_shadows.lit_pieces(below.origins[0], below.dirs[0], below.length[0], [0, 1, 0],
                                     [((-1, 0, -1), (1, 0, 1))])
    assert twin[-1][1] < below.length[0] - 0.1
    assert_same_pieces(list(zip(b.t0, b.t0 + b.length)), twin, 1e-14)


@pytest.mark.parametrize("offset", [0.0, 1e-9, -1e-9])
def test_a_light_on_a_surface_lights_the_room(offset):
    """A lamp on the ceiling of a closed room (exactly on it, or within the shadow-ray epsilon on
    either side) lights the whole room: the ceiling's triangles are taken as holding it."""
    room = box_triangles(*ROOM)
    lamp = [0.2, 2.0 + offset, 0.3]
    accel = Accelerator(room, np.array([lamp]))
    rng = np.random.default_rng(1)
    o = rng.uniform(-2.5, 2.5, (200, 3)) * [1, 0.7, 1.4]
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    t, _ = accel.first_hit(o, d)
    segs = whole_rays(o, d, t, np.arange(200, dtype=np.uint64), 1)
    lit, _ = exact_lit_intervals(accel, segs, lights_of("point", lamp), 1)
    assert np.array_equal(lit.ray, np.arange(200)) and np.all(lit.t0 == 0.0)
    np.testing.assert_allclose(lit.length, t, rtol=1e-14)


def test_segments_to_infinity_and_rays_through_the_light():
    """Rays to infinity past a box, and rays through the light itself (both ways), against the twin."""
    box = ((-0.5, -0.5, -0.5), (0.5, 0.5, 0.5))
    L = np.array([0.2, 1.7, -0.1])
    accel = Accelerator(box_triangles(*box), L[None])
    lights = lights_of("point", L)
    rng = np.random.default_rng(2)
    d = rng.normal(size=(64, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    starts = np.concatenate([rng.uniform(-3, 3, (64, 3)), L - 2.5 * d])  # the second half passes through L
    dirs = np.concatenate([d, d])
    segs = whole_rays(starts, dirs, np.full(128, np.inf), np.arange(128, dtype=np.uint64), 1)
    inside = np.array([np.all(np.abs(p) < 0.5) for p in starts])
    segs = segs.take(np.nonzero(~inside)[0])
    lit, _ = exact_lit_intervals(accel, segs, lights, 1)
    shadowed = 0
    for s in range(len(segs)):
        twin = oracle_shadows.lit_pieces(segs.origins[s], segs.dirs[s], math.inf, L, [box])
        assert_same_pieces(pieces_of(segs, lit, s), twin, 1e-12 * accel.scale)
        shadowed += twin != [(0.0, math.inf)]
    assert shadowed > 10


@pytest.mark.parametrize("kind", ["point", "sun"])
def test_degenerate_and_edge_on_triangles_cast_no_shadow(kind):
    """Zero-area triangles (a repeated vertex, three collinear vertices) and triangles whose plane
    holds a point light (or the sun's direction) change no interval."""
    L = np.array([0.1, 2.0, 0.2])
    box = box_triangles((-0.4, 0.0, -0.3), (0.3, 0.4, 0.5))
    extra = [[[0, 1, 0], [0, 1, 0], [1, 1, 1]], [[0, 0.5, 0], [1, 0.5, 0], [2, 0.5, 0]]]
    sun = np.array([0.3, -1.0, 0.2])
    if kind == "point":  # planes through the light
        extra += [[L + [1, 0, 0], L + [0, -3, 0], L + [2, -3, 0]], [L + [1, -2, 0], L + [0, -1, 2], L + [1, -3, 2]]]
    else:  # planes holding the sun's direction
        extra += [[[0, 1, 0], [0, 1, 0] + 3 * sun, [1, 1, 0]], [[-1, 0.2, 0], [-1, 0.2, 0] + 2 * sun, [-1, 0, 1]]]
    tris = np.concatenate([box, np.array(extra, float)])
    lights = lights_of(kind, L if kind == "point" else sun)
    rng = np.random.default_rng(3)
    o = rng.uniform(-2, 2, (300, 3)) + [0, -2.5, 0]
    d = rng.normal(size=(300, 3))
    segs = raw_segments(o, d, 6.0)
    a, _ = exact_lit_intervals(Accelerator(box, L[None]), segs, lights, 1)
    b, _ = exact_lit_intervals(Accelerator(tris, L[None]), segs, lights, 1)
    assert np.sum(np.bincount(a.ray, a.length, 300) < 6.0 - 1e-9) > 20  # the box shadows some rays
    assert np.array_equal(a.ray, b.ray)
    np.testing.assert_allclose(b.t0, a.t0, rtol=0, atol=1e-13)
    np.testing.assert_allclose(b.length, a.length, rtol=0, atol=1e-13)


@pytest.mark.parametrize("kind", ["point", "sun"])
def test_a_triangle_soup_against_brute_force(kind):
    """300 random triangles of all sizes: every lit piece's midpoint sees the light, and every
    shadowed gap's midpoint does not, by a float64 segment-triangle test against all triangles;
    and the resolution of the texel lists changes nothing (a speed hint only)."""
    rng = np.random.default_rng(4)
    centres = rng.uniform(-2, 2, (300, 3))
    size = 10.0 ** rng.uniform(-3, 0, (300, 1, 1))
    tris = centres[:, None, :] + size * rng.normal(size=(300, 3, 3))
    L = np.array([0.3, 3.0, -0.2])
    travel = np.array([-0.2, -1.0, 0.4])
    lights = lights_of(kind, L if kind == "point" else travel)
    accel = Accelerator(tris, L[None])
    o = rng.uniform(-3, 3, (150, 3))
    segs = raw_segments(o, rng.normal(size=(150, 3)), np.where(np.arange(150) % 5 == 0, np.inf, 5.0))
    lit, stats = exact_lit_intervals(accel, segs, lights, 1, build(accel, lights, 16))
    fine, _ = exact_lit_intervals(accel, segs, lights, 1, build(accel, lights, 64))
    assert np.array_equal(lit.ray, fine.ray)
    np.testing.assert_allclose(fine.t0, lit.t0, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(fine.length, lit.length, rtol=1e-13, atol=1e-13)
    assert stats[ST_NEAR] > 0
    checked = 0
    for s in range(len(segs)):
        pieces = pieces_of(segs, lit, s)
        ends = [0.0] + [x for p in pieces for x in p] + [segs.length[s]]
        for a, b in zip(ends[:-1], ends[1:]):
            if not b - a >= 1e-6:  # also the empty pair (inf, inf) after a piece to infinity
                continue
            mid = a + 0.5 * (b - a) if math.isfinite(b) else a + 1.0
            p = segs.origins[s] + mid * segs.dirs[s]
            seen = not oracle_shadows.triangles_block(p, L if kind == "point" else travel, tris, kind == "sun")
            assert seen == any(x0 <= mid <= x1 for x0, x1 in pieces), (s, mid)
            checked += 1
    assert checked > 300


def test_default_resolution():
    assert default_resolution(12) == 16 and default_resolution(75000) == 64 and default_resolution(10**8) == 256


# --- the paper's scenes against the sampled search at its finest spacing (slow) -------------------

def crop_segments(name):
    """32 x 32 pixels at the centre of the scene's own view (1 spp): segments cut to spot cones,
    with the normals of the surfaces they end on (for the sampled search)."""
    try:
        sc = raytrace.load(name, overrides=["camera.spp=1"])
    except raytrace.UserError as exc:
        if "not found" in str(exc):
            pytest.skip(f"mesh not on the asset path (set RAYTRACE_ASSETS=../shared/scenes): {exc}")
        raise
    prep = prepare(sc)
    cam = sc.camera
    x0, y0 = cam.width // 2 - 16, cam.height // 2 - 16
    o, d = generate_rays(cam, slice(y0, y0 + 32), slice(x0, x0 + 32))
    t, prim = prep.accel.first_hit(o, d)
    n = len(prep.lights)
    segs = whole_rays(o, d, t, np.zeros(len(o), np.uint64), n, 0, prep.accel.scale)
    normals = np.where((prim >= 0)[:, None], prep.accel.normals[np.maximum(prim, 0)], 0.0)
    segs, ends = cone_segments(segs, prep.lights, np.repeat(normals, n, axis=0))
    return prep, segs, ends, len(o)


def angle(lights, o, d, li, x):
    """The angle at which light li sees the point o + x d, from the ray's foot point."""
    L = lights.position[li]
    xh = float((L - o) @ d)
    h = float(np.linalg.norm(o + xh * d - L))
    return math.atan2(x - xh, h) if math.isfinite(x) else 0.5 * math.pi


@pytest.mark.slow
@pytest.mark.parametrize("name", ["sibenik", "bridge", "conference"])
def test_the_papers_scenes_agree_with_the_sampled_search_at_1e_5(name):
    """The sampled search that preceded the exact intervals (benchmarks/sampled_search.py) at spacing 1e-5 rad, its finest, misses only
    what is narrower than that and places what it finds to its float32 resolution: boundaries
    bisected to 3e-8 rad in float32 directions (6e-8), shadow rays stopped 4e-7 of their length
    short. Every piece it finds is an exact piece whose ends lie within 1e-6 rad seen from the light
    or 1e-6 of the scene's size along the ray, and analytic's air-light on the two sets of pieces
    agrees to 1e-5 per pixel. (Measured: see docs/exact_shadows.md.)"""
    from benchmarks.sampled_search import lit_intervals

    prep, segs, ends, n_rays = crop_segments(name)
    n = len(prep.lights)
    exact, _ = exact_lit_intervals(prep.accel, segs, prep.lights, n)
    sampled, _ = lit_intervals(prep.accel, segs, prep.lights, n, 1e-5, ends)
    method = get_method("analytic")
    params = resolve_params(method, {}, "test")
    a = segment_airlight(method, prep.scene.medium, prep.lights, params, exact, n_rays)[0]
    b = segment_airlight(method, prep.scene.medium, prep.lights, params, sampled, n_rays)[0]
    assert np.all(np.abs(a - b) <= 1e-5 * np.abs(b)), np.max(np.abs(a - b) / np.abs(b))
    key_e, key_s = exact.ray * n + exact.light, sampled.ray * n + sampled.light
    for j in range(len(sampled)):
        mine = np.nonzero(key_e == key_s[j])[0]
        s0, s1 = sampled.t0[j], sampled.t0[j] + sampled.length[j]
        overlap = np.minimum(s1, exact.t0[mine] + exact.length[mine]) - np.maximum(s0, exact.t0[mine])
        assert len(mine) and overlap.max() > 0.0, j
        i = mine[np.argmax(overlap)]
        o, w, li = sampled.origins[j] - sampled.t0[j] * sampled.dirs[j], sampled.dirs[j], sampled.light[j]
        for x, y in ((s0, exact.t0[i]), (s1, exact.t0[i] + exact.length[i])):
            if x == y:
                continue
            turn = abs(angle(prep.lights, o, w, li, x) - angle(prep.lights, o, w, li, y))
            assert turn <= 1e-6 or abs(x - y) <= 1e-6 * prep.accel.scale, (j, x, y, turn)


@pytest.mark.parametrize("kind", ["point", "sun"])
def test_without_triangles_every_segment_is_lit_whole(kind):
    accel = Accelerator(np.zeros((0, 3, 3)), np.zeros((1, 3)))
    segs = raw_segments(np.random.default_rng(5).normal(size=(20, 3)), [[0.0, 0.0, 1.0]] * 20,
                        np.where(np.arange(20) % 2, np.inf, 3.0))
    lit, stats = exact_lit_intervals(accel, segs, lights_of(kind, [0.0, -1.0, 0.2]), 1)
    assert np.array_equal(lit.ray, np.arange(20)) and np.array_equal(lit.length, segs.length)
    assert np.array_equal(lit.origins, segs.origins) and np.array_equal(lit.stream, segs.stream)
