"""A directional light and a camera inside convex refractive shapes of more face planes than the
index-matched kernel's KERNEL_PLANES (a glass icosphere of 320 triangles): the sun enters through every
face it meets, one refracted beam each, over the interval of each inside segment where the path back
along the beam leaves through that face (interiors/rows.py `_face_beams`, media/convex_directional.py
`beam_intervals`); a camera inside such a shape sees the sun's beams and a point light's Fermat paths
through every face (media/slab.py `faces_point`).

The twin uses the geometry alone (tests/test_refracted_mesh_faces.py's triangles): for each triangle
the sun meets, Snell's and Fresnel's laws by angles (tests/test_bounded_media.py) give the beam's
direction t and irradiance E T cos_i / cos_t; the point p(x) + s u (u = -t) where the path back meets
the triangle's plane lies in the triangle on an interval of x, from its barycentric coordinates, which
are linear in x (checked against the slab test's exit face at its midpoint); scipy quad integrates
ks Phi E exp(-sigma_t (x + s)) over it. The point light's twin is that file's Fermat twin.
"""
import math

import numpy as np
import pytest
import trimesh
from scipy import integrate

from raytrace.interiors import shapes
from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import scene_from_text

from . import oracle
from .conftest import to_toml
from .test_bounded_media import fresnel_t, snell
from .test_refracted_beams import plate_hit, plate_shape, switches
from .test_refracted_mesh_faces import barycentric, exit_distance, image, point_segment, triangles

SUN = {"type": "directional", "direction": [0.4, -1.0, -0.3], "irradiance": 3.0}
OUTSIDE = {"position": [0.3, 0.4, 3.2], "look_at": [0.0, 0.0, 0.0], "fov": 26.0, "width": 4, "height": 3, "spp": 1}
INSIDE = {"position": [0.2, 0.1, 0.3], "look_at": [0.0, -0.2, -1.0], "fov": 60.0, "width": 4, "height": 3, "spp": 1}


def ball(camera, light, subdivisions=2):
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    return {"name": f"glass_ico{subdivisions}", "camera": camera, "medium": {"sigma_a": 0.0, "sigma_s": 0.0},
            "shape": [{"primitive": "triangles", "vertices": mesh.vertices.tolist(), "faces": mesh.faces.tolist(),
                       "interior": {"sigma_a": [0.2, 0.1, 0.05], "sigma_s": [0.5, 0.4, 0.3],
                                    "phase": {"type": "hg", "g": 0.3}, "ior": 1.5}}],
            "light": [light]}


def sun_segment(scene, geometry, p, w, ell, plates=(), through=None):
    """The sun's single scattering (3,) over the inside segment p + x w, x in [0, ell] (module docstring);
    `plates`: black plates outside (tests/test_refracted_beams.py's), each beam's interval cut where the
    path from its entry point toward the sun meets one (bisected on that indicator); `through` =
    (attenuation (3,) of the entry point Y's path to the sun, the x in (0, d) where it kinks along
    Y0 + x Y' (Y0, Y', d), Y affine in x)."""
    tri, normals, offsets = geometry
    inner, sun = scene["shape"][0]["interior"], scene["light"][0]
    eta, g = inner["ior"], inner["phase"]["g"]
    ks = np.array(inner["sigma_s"], float)
    kt = np.array(inner["sigma_a"], float) + ks
    s = np.array(sun["direction"], float)
    s /= np.linalg.norm(s)
    out = np.zeros(3)
    for f in np.nonzero(normals @ s < 0.0)[0]:
        n, c = normals[f], offsets[f]
        t, ti, tt = snell(s, n, eta)
        e = sun["irradiance"] * fresnel_t(ti, tt, eta) * math.cos(ti) / math.cos(tt)
        u = -t
        depth = lambda x: (c - n @ (p + x * w)) / (n @ u)  # noqa: E731
        b0 = barycentric((p + depth(0.0) * u)[None, :], tri[f])[0]
        b1 = barycentric((p + ell * w + depth(ell) * u)[None, :], tri[f])[0]
        lo, hi = 0.0, ell
        for a, b in zip(b0, b1):  # a + (b - a) x / ell >= 0
            if b == a:
                hi = hi if a >= 0.0 else -1.0
            elif b > a:
                lo = max(lo, -a * ell / (b - a))
            else:
                hi = min(hi, -a * ell / (b - a))
        if not hi > lo:
            continue
        mid = p + 0.5 * (lo + hi) * w
        den = normals @ u
        k = np.where(den > 0.0, (offsets - normals @ mid) / np.where(den > 0.0, den, 1.0), np.inf)
        assert np.argmin(k) == f or k[np.argmin(k)] == k[f], (f, np.argmin(k))
        ph = oracle.phase("hg", g, float(u @ w))  # the light travels along -u, the eye is along -w

        def clear(X):
            return not any(plate_hit(X + depth(float((X - p) @ w)) * u, -s, q) < math.inf for q in plates)

        cuts = [lo] + [lo + x for x in switches(p + lo * w, w, hi - lo, clear)] + [hi]
        entry = lambda x: p + x * w + depth(x) * u  # noqa: E731
        attenuation = (lambda x: 1.0) if through is None else (lambda x: through[0](entry(x)))  # noqa: E731
        if through is not None:
            cuts = sorted(cuts + [lo + x for x in through[1](entry(lo), entry(lo + 1.0) - entry(lo), hi - lo)])
        for a, b in zip(cuts[:-1], cuts[1:]):
            if b > a and clear(p + 0.5 * (a + b) * w):
                out += e * ks * ph * integrate.quad_vec(lambda x: np.exp(-kt * (x + depth(x))) * attenuation(x), a, b,
                                                        epsabs=0.0, epsrel=1e-12)[0]
    return out


def twin(scene, geometry, segment):
    """The image's twin: each pixel's camera ray (from outside: refracted in at the first face, times
    T / eta^2; from inside: from the camera) and its inside segment's `segment` value."""
    tri, normals, offsets = geometry
    cam, eta = scene["camera"], scene["shape"][0]["interior"]["ior"]
    out = np.zeros((cam["height"], cam["width"], 3))
    for j in range(cam["height"]):
        for i in range(cam["width"]):
            o, d = oracle.camera_ray(cam, i, j)
            if np.all(normals @ o <= offsets):  # inside
                out[j, i] = segment(scene, geometry, o, d, exit_distance(o, d, normals, offsets))
                continue
            den = normals @ d
            t = (offsets - normals @ o) / den
            t_in, f_in = np.max(np.where(den < 0.0, t, -np.inf)), np.argmax(np.where(den < 0.0, t, -np.inf))
            if not t_in < np.min(np.where(den > 0.0, t, np.inf)) or t_in <= 0.0:
                continue
            p = o + t_in * d
            w, ti, tt = snell(d, normals[f_in], eta)
            out[j, i] = fresnel_t(ti, tt, eta) / eta**2 * segment(scene, geometry, p, w,
                                                                  exit_distance(p, w, normals, offsets))
    return out


def check(scene, ref, method, params, tol, median, shadows=False):
    """The render against the twin `ref`: within tol on the lit pixels (every pixel lit but with
    `shadows`), the bound finite and above the error on every pixel, its median over the value at
    most `median`."""
    res = (render(prepare(scene_from_text(to_toml(scene), scene["name"])), method, params,
                  RenderOptions(threads=1, volumetric_shadows=True)) if shadows else image(scene, method, params))
    err = np.abs(res.image - ref)
    lit = ref > 0.0
    assert np.all(lit[..., 1]) or shadows, lit[..., 1]
    assert np.max(err[lit] / ref[lit]) < tol, np.max(err[lit] / ref[lit])
    assert np.all(err <= res.error_bound), np.max(err / res.error_bound)
    assert np.all(np.isfinite(res.error_bound))
    assert np.median(res.error_bound[lit] / ref[lit]) <= median
    return res


@pytest.mark.parametrize("camera", [OUTSIDE, INSIDE], ids=["outside", "inside"])
def test_the_sun_through_every_face_of_a_320_face_ball(camera):
    """quadrature (rtol 1e-6) within 1e-6 of the twin on every pixel, seen from outside and from a
    camera inside, and analytic (the closed form) within 1e-9 from outside; the bounds finite and above
    the error on every pixel, their median at most 10 rtol of the value (quadrature) and 1e-7
    (analytic: 1.8e-8, most of it the span where each beam's ends may lie, 1e-11 per end and beam
    at planes 9e-13 off; its error 8.5e-11). Before, the ball took the sun through the entry face's plane alone (outside: more
    than 10 % off; inside: refused)."""
    scene = ball(camera, SUN)
    prep = prepare(scene_from_text(to_toml(scene), scene["name"]))
    assert len(shapes.refracting_planes(prep, 0)) == 320 > shapes.KERNEL_PLANES
    geometry = triangles(scene)
    ref = twin(scene, geometry, sun_segment)
    check(scene, ref, "quadrature", {"rtol": 1e-6}, 1e-6, 1e-5)
    if camera is OUTSIDE:  # analytic takes no camera inside a shape
        check(scene, ref, "analytic", {}, 1e-9, 1e-7)


PLATE = (1, 1.625, (-1.5, -1.5), (-0.375, 1.5))  # y = 1.625, x in [-1.5, -0.375], z in [-1.5, 1.5]: above part of the ball (float32 values)


def test_a_plate_shadows_the_beams():
    """Volumetric shadows: a black plate above part of the ball cuts the beams where their
    entry points' paths to the sun meet it (rows.py `_lit_beams`, shadows/beams.py); quadrature
    within 1e-6 and analytic within 1e-9 (1.0e-10) of the twin with the plate on every lit pixel,
    their bounds finite and above the error, and not vacuous: the plate darkens some
    pixels by more than 10 % and leaves at least half of them lit (before, these beams were
    unshadowed, the bound infinite)."""
    scene = ball(OUTSIDE, SUN)
    geometry = triangles(scene)
    scene["shape"].append(plate_shape(PLATE))
    ref = twin(scene, geometry, lambda *a: sun_segment(*a, plates=[PLATE]))
    free = twin(ball(OUTSIDE, SUN), geometry, sun_segment)
    assert np.max(1.0 - ref[..., 1] / free[..., 1]) > 0.1 and np.count_nonzero(ref[..., 1] > 0.0) >= 6
    res = check(scene, ref, "quadrature", {"rtol": 1e-6}, 1e-6, 1e-5, shadows=True)
    assert res.stats["inside: lit pieces"] > 0
    check(scene, ref, "analytic", {}, 1e-9, 1e-7, shadows=True)


def test_a_camera_inside_a_320_face_ball_under_a_lamp():
    """A point light outside, the camera inside: quadrature within 1e-6 of the Fermat twin on every
    pixel, its bound finite and above the error (refused before: a camera inside needed at most
    KERNEL_PLANES planes)."""
    scene = ball(INSIDE, {"type": "point", "position": [0.6, 2.0, -2.2], "intensity": [8.0, 6.0, 5.0]})
    scene["medium"] = {"sigma_a": 0.01}
    ref = twin(scene, triangles(scene), point_segment)
    check(scene, ref, "quadrature", {"rtol": 1e-6}, 1e-6, 1e-5)


@pytest.mark.parametrize("case", ["underwater lamp", "underwater sun", "index-matched U"])
def test_a_camera_inside_keeps_its_bound(case, tmp_path):
    """The renderer now keeps the crossing's error bound for a camera inside a shape (it was infinite
    on every pixel): against the existing twins of a camera inside a convex refractive box
    (tests/test_underwater_camera.py: quadrature's refracted beams and Fermat paths, rtol 1e-11) and
    inside a non-convex index-matched U (tests/test_inside_paths.py, rtol 1e-10), the bound is above
    the error on every pixel, and finite on every pixel of the U."""
    from raytrace.scene.format import load_scene

    from . import test_inside_paths as u
    from . import test_underwater_camera as water

    if case == "index-matched U":
        (tmp_path / "u.obj").write_text(u.u_obj())
        sc = u.u_scene(u.LIGHTS["lamp"])
        sc["camera"].update(position=[-0.7, 0.1, 0.3], look_at=[1.0, -0.2, -0.2], fov=60.0, width=8, height=5)
        (tmp_path / "u.toml").write_text(to_toml(sc))
        prep = prepare(load_scene(tmp_path / "u.toml"))
        assert prep.camera_inside == 0
        ref = u.twin_image(sc)
        res = render(prep, "quadrature", {"rtol": 1e-10}, RenderOptions(threads=1))
    else:
        light = water.LAMP if case == "underwater lamp" else water.SUN
        ref, _ = water.twin_image(light)
        res = image({**water.SCENE, "light": [light]}, "quadrature", {"rtol": 1e-11})
    err = np.abs(res.image - ref)
    assert np.all(err <= res.error_bound), np.max(err / res.error_bound)
    if case == "index-matched U":
        assert np.all(np.isfinite(res.error_bound))


def test_the_beam_intervals_and_their_spans():
    """media/convex_directional.py `beam_intervals` on random chords of the 320-face ball, every beam of
    the sun (its direction from the twin's Snell): the computed ends lie in their spans (lo_a <= lo <=
    lo_b, hi_a <= hi <= hi_b), and the twin's interval (barycentric in the triangle, `sun_segment`'s
    rule) inside the spans of the planes' measured errors against the triangles (interiors/shapes.py
    `measured_plane_errors`; one end 1.2e-10 from the twin's, inside its span); with the planes taken
    1e-6 off, the spans widen about the same ends. Swapped upper spans (fixed before merging) failed
    here and cut the shadowed beams 6e-9 short."""
    from raytrace.media.convex_directional import beam_intervals

    scene = ball(OUTSIDE, SUN)
    tri, normals, offsets = triangles(scene)
    prep = prepare(scene_from_text(to_toml(scene), scene["name"]))
    planes = shapes.refracting_planes(prep, 0)
    near = shapes.plane_neighbours(prep, 0)
    dplanes = shapes.measured_plane_errors(prep, 0)  # the planes against the triangles
    rng = np.random.default_rng(3)
    o = rng.normal(size=(40, 3))
    o *= (0.9 * rng.random(40) ** (1 / 3) / np.linalg.norm(o, axis=1))[:, None]
    w = rng.normal(size=(40, 3))
    w /= np.linalg.norm(w, axis=1)[:, None]
    ell = np.array([exit_distance(p, d, planes[:, :3], planes[:, 3]) for p, d in zip(o, w)])
    s = np.array(SUN["direction"], float) / np.linalg.norm(SUN["direction"])
    ints, wide = np.empty((40, 9)), np.empty((40, 9))
    checked = 0
    for f in np.nonzero(planes[:, :3] @ s < 0.0)[0]:
        t, _, _ = snell(s, planes[f, :3], 1.5)
        u = np.ascontiguousarray(-t)
        beam_intervals(np.ascontiguousarray(planes[:, :3]), np.ascontiguousarray(planes[:, 3]), near, int(f), u, o, w,
                       ell, dplanes, 0.0, ints)
        beam_intervals(np.ascontiguousarray(planes[:, :3]), np.ascontiguousarray(planes[:, 3]), near, int(f), u, o, w,
                       ell, np.array([1e-6, 1e-6]), 0.0, wide)
        for r in (ints, wide):
            assert np.all((r[:, 2] <= r[:, 0]) & (r[:, 0] <= r[:, 3]) | (r[:, 0] >= r[:, 1]))
            assert np.all((r[:, 4] <= r[:, 1]) & (r[:, 1] <= r[:, 5]) | (r[:, 0] >= r[:, 1]))
        assert np.all(wide[:, 2] <= ints[:, 2]) and np.all(wide[:, 5] >= ints[:, 5])
        k = int(np.argmin(np.linalg.norm(normals - planes[f, :3], axis=1)))  # the triangle in plane f
        for i in range(40):
            depth = lambda x: (planes[f, 3] - planes[f, :3] @ (o[i] + x * w[i])) / (planes[f, :3] @ u)  # noqa: E731
            b0 = barycentric((o[i] + depth(0.0) * u)[None, :], tri[k])[0]
            b1 = barycentric((o[i] + ell[i] * w[i] + depth(ell[i]) * u)[None, :], tri[k])[0]
            lo, hi = 0.0, ell[i]
            for a, b in zip(b0, b1):
                if b > a:
                    lo = max(lo, -a * ell[i] / (b - a))
                elif b < a:
                    hi = min(hi, -a * ell[i] / (b - a))
                elif a < 0.0:
                    hi = -1.0
            if hi > lo + 1e-9:
                assert ints[i, 2] <= lo <= ints[i, 3] and ints[i, 4] <= hi <= ints[i, 5], (ints[i], lo, hi)
                checked += 1
    assert checked > 40, checked
