"""geometry/facet_walk.py: the facets through which light paths from a camera segment leave a convex mesh.

Against brute force in NumPy that knows nothing of the walk: the nearest face plane ahead of each of
dense points along random chords of a sphere, a convex hull of random points and a box (whose faces
are pairs of coplanar triangles), toward point lights outside and inside and a directional light;
the changes of that plane bisected to 1e-13. Then images of a tessellated sphere, through the walk
(Embree's exits) and through media/slab.py's plane kernel, against a twin that integrates the
same faceted sphere with scipy between the bisected changes.
"""

import numpy as np
import pytest
from scipy import integrate
from scipy.spatial import ConvexHull

from raytrace.geometry import facet_walk
from raytrace.interiors import paths, shapes
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text
from raytrace.scene.meshes import box_triangles, sphere_triangles

from . import oracle
from .conftest import to_toml
from .test_interiors_scale import normals_of, real


def hull_triangles(n, seed):
    pts = np.random.default_rng(seed).normal(size=(n, 3))
    return pts[ConvexHull(pts).simplices]


MESHES = {
    "sphere": lambda: real(sphere_triangles(np.zeros(3), 1.0, 100)),
    "hull": lambda: hull_triangles(300, 3),
    "box": lambda: box_triangles(np.array([-1.0, -0.5, -0.7]), np.array([1.2, 0.6, 0.9])),
}


def nearest_plane(planes, p, to, dist):
    """(length, plane row) of the path from p along to until it leaves {n . q <= c}, at most dist."""
    den = planes[:, :3] @ to
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(den > 0.0, (planes[:, 3] - planes[:, :3] @ p) / den, np.inf)
    f = int(np.argmin(t))
    return min(t[f], dist), planes[f]


def chords(planes, rng, n):
    """Random chords (entry point, unit direction, length) of the convex shape."""
    out = []
    while len(out) < n:
        p = rng.normal(size=3) * 0.3
        if np.any(planes[:, :3] @ p > planes[:, 3]):
            continue
        w = rng.normal(size=3)
        w /= np.linalg.norm(w)
        back = nearest_plane(planes, p, -w, np.inf)[0]
        ahead = nearest_plane(planes, p, w, np.inf)[0]
        out.append((p - back * w, w, back + ahead))
    return out


def toward(light, directional, q):
    if directional:
        return light, np.inf
    rel = light - q
    d = np.linalg.norm(rel)
    return rel / d, d


def assert_exits(planes, walked, s, o, w, x, source, directional):
    """The exit lengths of `walked` (facet_walk.pieces' arrays) at the points x of segment s (entry o,
    direction w) agree with the nearest face plane ahead to 1e-12."""
    p = o + x[:, None] * w
    to = np.array([toward(source, directional, q)[0] for q in p])
    dist = np.array([toward(source, directional, q)[1] for q in p])
    got = np.empty(len(x))
    facet_walk.exit_lengths(np.full(len(x), s), x, p, to, dist, *walked, planes, 0.0, got, np.empty(len(x)))
    want = np.array([nearest_plane(planes, q, u, d)[0] for q, u, d in zip(p, to, dist)])
    assert np.max(np.abs(got - want)) < 1e-12, (s, got, want)


@pytest.mark.parametrize("mesh", sorted(MESHES))
@pytest.mark.parametrize("light", ["point", "inside", "directional"])
def test_the_walk_finds_every_change_of_exit_facet(mesh, light):
    tris = MESHES[mesh]()
    links = facet_walk.mesh_links(tris, normals_of(tris))
    planes = links[0]
    rng = np.random.default_rng(7)
    directional = light == "directional"
    source = {"point": np.array([2.5, 1.8, -1.2]), "inside": np.array([0.1, -0.05, 0.2]),
              "directional": np.array([0.48, 0.8, -0.36])}[light]
    segs = chords(planes, rng, 40)
    geo = np.array([[*o, *w, *source] for o, w, _ in segs])
    end = np.array([ell for _, _, ell in segs])
    start = []
    for (o, w, ell) in segs:
        q = o + 0.5 * ell * w
        to, d = toward(source, directional, q)
        den = planes[:, :3] @ to
        with np.errstate(divide="ignore", invalid="ignore"):
            start.append(int(np.argmin(np.where(den > 0.0, (planes[:, 3] - planes[:, :3] @ q) / den, np.inf))))
    offsets, counts, bt, bf = facet_walk.pieces(links, geo, directional, end, np.array(start))
    assert np.all(counts >= 0), counts
    changes = 0
    for s, (o, w, ell) in enumerate(segs):
        x = np.linspace(0.0, ell, 801)[1:-1]
        assert_exits(planes, (offsets, counts, bt, bf), s, o, w, x, source, directional)
        if light == "inside":
            continue
        br = bt[offsets[s]:offsets[s + 1]]
        assert np.all(np.diff(br) > 0.0) and np.all((br > 0.0) & (br < ell))

        def plane_at(t):
            q = o + t * w
            return nearest_plane(planes, q, *toward(source, directional, q))[1]
        for a, b in zip(x[:-1], x[1:]):  # each change of the exit plane has a breakpoint within 1e-9
            if np.allclose(plane_at(a), plane_at(b), atol=1e-9):
                continue
            for _ in range(50):
                m = 0.5 * (a + b)
                a, b = (m, b) if np.allclose(plane_at(m), plane_at(a), atol=1e-9) else (a, m)
            assert np.min(np.abs(br - a)) < 1e-9 * ell, (s, a)
            changes += 1
        mids = 0.5 * (np.concatenate([[0.0], br]) + np.concatenate([br, [ell]]))
        facets = bf[offsets[s] + s:offsets[s + 1] + s + 1]
        for t, f in zip(mids, facets):  # the facet of every piece carries the exit plane
            assert np.allclose(planes[f], plane_at(t), atol=1e-9)
    if light != "inside":  # the walks had kinks to find
        assert changes >= {"sphere": 200, "hull": 40, "box": 20}[mesh], changes


def test_an_open_mesh_has_no_links():
    tris = real(sphere_triangles(np.zeros(3), 1.0, 24))
    assert facet_walk.mesh_links(tris[1:], normals_of(tris[1:])) is None


SCENE = {"camera": {"position": [0.0, 0.5, 3.0], "look_at": [0.0, 0.0, 0.0], "fov": 40.0, "width": 12,
                    "height": 8, "spp": 1},
         "shape": [{"primitive": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "segments": 24,
                    "interior": {"sigma_a": [0.3, 0.2, 0.1], "sigma_s": [0.5, 0.4, 0.3],
                                 "phase": {"type": "hg", "g": 0.4}}}]}
LIGHTS = {"point": {"medium": {"sigma_a": 0.02}, "light": [{"type": "point", "position": [2.0, 2.0, 1.0],
                                                            "intensity": 5.0}]},
          "directional": {"light": [{"type": "directional", "direction": [-0.3, -1.0, -0.2], "irradiance": 2.0}]}}


def faceted_pixel(sc, planes, i, j):
    """The single scattering along the pixel's centre ray inside the faceted sphere {n . q <= c}:
    scipy between the bisected changes of the exit plane of the light's path."""
    o, w = oracle.camera_ray(sc["camera"], i, j)
    with np.errstate(divide="ignore", invalid="ignore"):
        den = planes[:, :3] @ w
        t = (planes[:, 3] - planes[:, :3] @ o) / den
        t0, t1 = np.max(t[den < 0.0], initial=0.0), np.min(t[den > 0.0])
    if not t1 > t0:
        return np.zeros(3)
    inner = sc["shape"][0]["interior"]
    ks = np.array(inner["sigma_s"])
    kt = np.array(inner["sigma_a"]) + ks
    kt_out = sc.get("medium", {}).get("sigma_a", 0.0)
    light = sc["light"][0]
    directional = light["type"] == "directional"
    source = -np.array(light["direction"], float) / np.linalg.norm(light["direction"]) if directional \
        else np.array(light["position"], float)
    strength = light["irradiance"] if directional else light["intensity"]

    def path(x):
        q = o + (t0 + x) * w
        to, d = toward(source, directional, q)
        k, plane = nearest_plane(planes, q, to, d)
        return to, d, k, plane

    def f(x):
        to, d, k, _ = path(x)
        ph = oracle.phase("hg", inner["phase"]["g"], float(to @ w))
        if directional:
            return strength * ks * ph * np.exp(-kt * (x + k))
        return strength * ks * ph * np.exp(-kt_out * t0 - kt * (x + k) - kt_out * (d - k)) / d**2

    ell = t1 - t0
    xs = np.linspace(0.0, ell, 2001)
    br = [0.0]
    for a, b in zip(xs[:-1], xs[1:]):
        if not np.allclose(path(a)[3], path(b)[3], atol=1e-9):
            for _ in range(55):
                m = 0.5 * (a + b)
                a, b = (m, b) if np.allclose(path(m)[3], path(a)[3], atol=1e-9) else (a, m)
            br.append(a)
    br.append(ell)
    return sum(integrate.quad_vec(f, a, b, epsabs=0.0, epsrel=1e-13)[0] for a, b in zip(br[:-1], br[1:]))


@pytest.mark.parametrize("light", sorted(LIGHTS))
@pytest.mark.parametrize("route", ["walk", "kernel"])
def test_a_tessellated_sphere_matches_the_faceted_twin(light, route):
    """quadrature (rtol 1e-10) within 1e-9 of the twin on every lit pixel, the light's exits found by
    the walk (24 segments: 300 face planes, beyond shapes.KERNEL_PLANES; Embree's facet to start
    from) or by media/slab.py's kernel (8 segments: 32 planes, each tested at every evaluation, the
    kinks from convex_directional.envelope and convex_chords.section_kinks). Before, the kernel was
    3e-9 off under the point light (its kinks inside panels) and 24 % under the directional one
    (the phase cosine of light mirrored off entry faces met from behind)."""
    segments = 24 if route == "walk" else 8
    sc = {**SCENE, **LIGHTS[light], "shape": [SCENE["shape"][0] | {"segments": segments}]}
    prep = prepare(scene_from_text(to_toml(sc), "sphere"))
    planes = shapes.hull_planes(prep, 0)
    assert (len(shapes.convex_planes(prep, 0)) > 0) == (route == "kernel")
    img = render(prep, "quadrature", {}, RenderOptions(threads=1)).image
    worst, lit = 0.0, 0
    for j in range(sc["camera"]["height"]):
        for i in range(sc["camera"]["width"]):
            want = faceted_pixel(sc, planes, i, j)
            if np.all(want == 0.0):
                assert np.all(img[j, i] == 0.0)
                continue
            lit += 1
            worst = max(worst, float(np.max(np.abs(img[j, i] - want) / want)))
    print(f"{route}, {light} light: largest relative error {worst:.2e} over {lit} pixels")
    assert lit > 30 and worst < 1e-9


@pytest.mark.parametrize("mesh", ["sphere32", "box"])
@pytest.mark.parametrize("light", ["point", "directional"])
def test_segments_entering_on_an_edge_toward_the_light_are_walked(mesh, light):
    """A camera segment entering the shape on an edge of a facet that faces the light starts on the
    cut polygon at an edge crossing (its exit is its entry point): the walk ends there within
    rounding, instead of stepping past the segment's start and finding its breakpoints out of order
    (such segments were handed back to Embree: 1 of 48 in a 12 x 8 image of a 32-segment sphere).
    Every such segment is walked, and its exits match the nearest face plane ahead."""
    tris = real(sphere_triangles(np.zeros(3), 1.0, 32)) if mesh == "sphere32" else MESHES["box"]()
    links = facet_walk.mesh_links(tris, normals_of(tris))
    planes, verts, tv, nbr = links
    directional = light == "directional"
    source = np.array([0.48, 0.8, -0.36]) if directional else np.array([2.5, 1.8, -1.2])
    rows, ends, starts = [], [], []
    for f in range(len(tv)):
        if not planes[f, :3] @ source > (0.0 if directional else planes[f, 3]):
            continue  # the facet does not face the light
        for k in range(3):
            o = 0.5 * (verts[tv[f, k]] + verts[tv[f, (k + 1) % 3]])  # the middle of an edge
            w = -(planes[f, :3] + planes[nbr[f, k], :3])
            w = w / np.linalg.norm(w) + 0.3 * np.cross(w / np.linalg.norm(w), [0.3, 0.5, 0.8])
            w /= np.linalg.norm(w)
            ell = nearest_plane(planes, o, w, np.inf)[0]
            q = o + 0.5 * ell * w
            rows.append([*o, *w, *source])
            ends.append(ell)
            starts.append(int(np.flatnonzero((planes == nearest_plane(planes, q, *toward(source, directional, q))[1])
                                             .all(axis=1))[0]))
    geo, end = np.array(rows), np.array(ends)
    offsets, counts, bt, bf = facet_walk.pieces(links, geo, directional, end, np.array(starts))
    assert len(counts) > 15 and np.all(counts >= 0), np.sum(counts < 0)
    for s in range(0, len(end), max(1, len(end) // 40)):
        assert_exits(planes, (offsets, counts, bt, bf), s, geo[s, :3], geo[s, 3:6], np.linspace(0.0, end[s], 41)[1:-1],
                     source, directional)


def test_first_panels_go_in_groups_of_whole_segments(monkeypatch):
    """The walk gives a segment of a fine mesh hundreds of first panels; `adaptive` takes them in
    groups of whole segments of about MAX_OPEN panels (memory bounded whatever the image), with the
    same image bit for bit as in one group."""
    sc = {**SCENE, **LIGHTS["point"], "shape": [SCENE["shape"][0] | {"segments": 24}]}
    prep = prepare(scene_from_text(to_toml(sc), "sphere"))
    want = render(prep, "quadrature", {}, RenderOptions(threads=1)).image
    calls = []  # per call of `adaptive`, the segments of each group
    outer, whole = paths.adaptive, paths._adaptive

    def spy_outer(*args, **kwargs):
        calls.append([])
        return outer(*args, **kwargs)

    def spy(integrand, end, nc, seg, a, b, rtol, stats, *bound):
        calls[-1].append(seg.copy())
        return whole(integrand, end, nc, seg, a, b, rtol, stats, *bound)
    monkeypatch.setattr(paths, "adaptive", spy_outer)
    monkeypatch.setattr(paths, "_adaptive", spy)
    monkeypatch.setattr(paths, "MAX_OPEN", 40)
    got = render(prep, "quadrature", {}, RenderOptions(threads=1)).image
    assert max(len(groups) for groups in calls) > 5
    for groups in calls:
        seen = np.concatenate([np.unique(g) for g in groups])
        assert len(seen) == len(np.unique(seen))  # no segment split between groups
        assert max(len(g) - np.count_nonzero(g == g[-1]) for g in groups) < 40  # full before its last segment
    assert np.array_equal(got, want)


def walked_exits_are_right(links, geo, directional, end, start):
    """For every segment the walk calls sound (counts >= 0), its exit lengths at 9 points agree
    with the nearest face plane ahead to 1e-12; returns the counts."""
    walked = facet_walk.pieces(links, geo, directional, end, start)
    for s in np.flatnonzero(walked[1] >= 0):
        assert_exits(links[0], walked, s, geo[s, :3], geo[s, 3:6], np.linspace(0.0, end[s], 11)[1:-1], geo[s, 6:9],
                     directional)
    return walked[1]


def prism_triangles(n=80, radius=0.1, half=25.0):
    a = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    ring = np.column_stack([radius * np.cos(a), radius * np.sin(a)])
    pts = np.concatenate([np.column_stack([ring, np.full(n, -half)]), np.column_stack([ring, np.full(n, half)])])
    return pts[ConvexHull(pts).simplices]


def test_a_point_light_on_a_vertex_or_an_edge():
    """The cut polygon passes through the light: the walk hands the segment back to Embree (it
    divided by zero); every segment it keeps is right."""
    tris = real(sphere_triangles(np.zeros(3), 1.0, 24))
    links = facet_walk.mesh_links(tris, normals_of(tris))
    planes, verts, tv, _ = links
    rng = np.random.default_rng(5)
    segs = chords(planes, rng, 30)
    for light in (verts[tv[40, 0]], 0.5 * (verts[tv[77, 0]] + verts[tv[77, 1]])):
        geo = np.array([[*o, *w, *light] for o, w, _ in segs])
        end = np.array([ell for _, _, ell in segs])
        start = [int(np.flatnonzero((planes == nearest_plane(planes, q, *toward(light, False, q))[1]).all(axis=1))[0])
                 for q in geo[:, :3] + 0.5 * end[:, None] * geo[:, 3:6]]
        walked_exits_are_right(links, geo, False, end, np.array(start))


def test_a_segment_entering_at_a_corner_stays_on_the_facets_facing_the_light():
    """A box corner on two faces toward the light: the cutting plane touches the start facet at that
    corner only, its crossings tie, and the walk stepped onto the faces turned away (exits 2.7
    where they are 0.01); now every facet it steps onto must face the light."""
    tris = MESHES["box"]()
    links = facet_walk.mesh_links(tris, normals_of(tris))
    planes = links[0]
    light = np.array([2.5, 1.8, -1.2])
    o = np.array([1.2, 0.6, 0.9])
    w = np.array([-0.8400716254429781, -0.4406833739768666, -0.31635079899686974])
    ell = nearest_plane(planes, o + 1e-9 * w, w, np.inf)[0] + 1e-9
    q = o + 0.5 * ell * w
    start = int(np.flatnonzero((planes == nearest_plane(planes, q, *toward(light, False, q))[1]).all(axis=1))[0])
    walked_exits_are_right(links, np.array([[*o, *w, *light]]), False, np.array([ell]), np.array([start]))


def test_embree_s_neighbour_facet_does_not_put_the_light_inside():
    """A thin 80-gon prism, the light outside a side facet but inside the cap's plane, and the start
    facet the cap across the rim edge (Embree's float32 hit 1e-9 from that edge): the walk took the
    light for inside (exits 0.55 where they are 0.05); whether it is inside is now asked of every
    face plane."""
    tris = prism_triangles()
    links = facet_walk.mesh_links(tris, normals_of(tris))
    planes, verts, tv, nbr = links
    side = next(f for f in range(len(tv)) if abs(planes[f, 2]) < 1e-9 and np.sum(np.isclose(verts[tv[f], 2], 25.0)) == 2)
    k = next(k for k in range(3) if np.isclose(verts[tv[side, k], 2], 25.0)
             and np.isclose(verts[tv[side, (k + 1) % 3], 2], 25.0))
    cap = nbr[side, k]
    exit_point = 0.5 * (verts[tv[side, k]] + verts[tv[side, (k + 1) % 3]]) - np.array([0.0, 0.0, 1e-9])
    u = planes[side, :3] - np.array([0.0, 0.0, 0.3])
    u /= np.linalg.norm(u)
    light = exit_point + 0.5 * u
    assert planes[cap, :3] @ light < planes[cap, 3]  # inside the cap's plane, outside the side's
    middle = exit_point - 0.05 * u
    w = np.cross(u, [0.0, 0.0, 1.0])
    w /= np.linalg.norm(w)
    back, ahead = nearest_plane(planes, middle, -w, np.inf)[0], nearest_plane(planes, middle, w, np.inf)[0]
    geo = np.array([[*(middle - back * w), *w, *light]])
    walked_exits_are_right(links, geo, False, np.array([back + ahead]), np.array([cap]))
