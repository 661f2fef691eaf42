"""Directional light (the sun) into a refractive shape that is not convex (media/nonconvex_directional.py,
interiors/rows.py `_sun_faces`) against a twin from the triangles alone.

The shape is the glass U of tests/test_nonconvex_refraction.py (ior 1.5, a fog inside, vacuum outside) under a sun
that comes from behind it, so that the face the camera sees it through looks away from the sun: the entry plane's
model (the sun refracted through the plane of the face the camera ray entered by) leaves those pixels black. The
twin knows the OBJ's triangles only: at each point X inside, for every triangle (its normal turned toward the sun)
the sun's direction refracted through it by Snell's vector law; X is lit through it where the ray from X back
along that direction first meets that triangle (its own Moller-Trumbore) and the ray from there toward the sun
meets none; the irradiance is Fresnel's transmittance in its angle form times cos_i / cos_t. The breaks along a
camera segment where the set of lit triangles changes are found on a grid of 400 points and bisected; scipy `quad`
integrates between them. The twin takes about 10 s: tests/make_nonconvex_sun_twins.py stores its values in
tests/data/nonconvex_sun_twins.json.
"""
import json
import pathlib

import numpy as np
import pytest
from scipy import integrate

from raytrace.options import RenderOptions
from raytrace.rendering.renderer import prepare, render
from raytrace.scene.format import load_scene

from . import oracle
from .conftest import to_toml
from .test_inside_paths import G, KA, KS, u_obj
from .test_nonconvex_refraction import CAMERA, ETA, NORMALS, first, hits, inside_stretch, refract, transmittance

AXIS = np.array([-0.6, -0.3, 0.5]) / np.linalg.norm([-0.6, -0.3, 0.5])  # travels toward +z: from behind the U
SUN = {"type": "directional", "direction": AXIS.tolist(), "irradiance": 2.0}
TWINS = pathlib.Path(__file__).with_name("data") / "nonconvex_sun_twins.json"  # tests/make_nonconvex_sun_twins.py
PIXELS = [(2, 1), (3, 2), (6, 2), (7, 3), (4, 4), (5, 5), (3, 5)]  # the arms, the base, the notch's floor


def beams(X):
    """(direction of travel inside, irradiance, path length inside) of every beam that reaches X."""
    out = []
    for f in range(len(NORMALS)):
        n = NORMALS[f] * (-1.0 if NORMALS[f] @ AXIS > 0 else 1.0)
        cos_i = -float(AXIS @ n)
        d = refract(AXIS, n, ETA) if cos_i > 0 else None
        if d is None:
            continue
        s, k = first(X, -d, tmin=0.0)
        if k != f or not np.isfinite(s):
            continue
        t = hits(X - s * d, -AXIS)
        t[f] = np.inf
        if np.any(np.isfinite(t) & (t > 1e-9)):
            continue
        cos_t = -float(d @ n)
        out.append((f, d, SUN["irradiance"] * transmittance(cos_i, ETA) * cos_i / cos_t, s))
    return out


def twin_pixel(i, j):
    """The pixel's radiance (3,), or None where the camera ray's light is not the one inside stretch the twin
    follows (its reflection or its way out meets the U again)."""
    stretch = inside_stretch(*oracle.camera_ray(CAMERA, i, j))
    if stretch is None:
        return None
    _, cos_i, P, w, ell = stretch
    kt = KA + KS

    def signature(x):
        return frozenset(f for f, _, _, _ in beams(P + x * w))

    cuts = oracle.set_changes(signature, ell)
    total = np.zeros(3)
    for a, b in zip(cuts, cuts[1:]):  # the lit set is constant in between: each beam's leg back to its own triangle
        for f, u, e, _ in beams(P + 0.5 * (a + b) * w):
            ph = oracle.phase("hg", G, float(-u @ w))

            def value(x, f=f, u=u):
                return np.exp(-kt * (x + hits(P + x * w, -u)[f]))
            total += KS * ph * e * integrate.quad_vec(value, a, b, epsabs=0.0, epsrel=1e-12)[0]
    return transmittance(cos_i, ETA) / ETA ** 2 * total


def scene(tmp_path):
    (tmp_path / "u.obj").write_text(u_obj())
    sc = {"camera": CAMERA, "shape": [{"mesh": "u.obj", "interior": {"sigma_a": KA.tolist(), "sigma_s": KS.tolist(),
                                                                     "phase": {"type": "hg", "g": G}, "ior": ETA}}],
          "light": [SUN]}
    path = tmp_path / "u.toml"
    path.write_text(to_toml(sc))
    return prepare(load_scene(path))


@pytest.fixture(scope="module")
def twins():
    """The stored twin's values, made for this very sun, camera and pixels."""
    stored = json.loads(TWINS.read_text())
    assert stored["sun"] == SUN and stored["camera"] == CAMERA
    assert [(i, j) for i, j, _ in stored["twins"]] == PIXELS
    return {(i, j): np.array(v) for i, j, v in stored["twins"]}


@pytest.fixture(scope="module")
def prep(tmp_path_factory):
    return scene(tmp_path_factory.mktemp("sun"))


def test_the_twin_still_agrees_with_its_stored_values(twins):
    """One pixel's twin recomputed (about 1 s), so that the stored file cannot drift from the twin."""
    assert np.allclose(twin_pixel(*PIXELS[5]), twins[PIXELS[5]], rtol=1e-12, atol=0.0)


def test_quadrature_and_analytic_match_the_twin(prep, twins):
    """quadrature (rtol 1e-6) within 1e-6 of the twin and analytic's closed form on each lit piece within 1e-9, on
    pixels of both arms and the base, most of whose camera rays enter through the face that looks away from the sun
    (the entry plane's model: 0). With volumetric shadows (nothing but the U in the scene) the image is the same, its
    segments counted unshadowed."""
    quad = render(prep, "quadrature", {"rtol": 1e-6}, RenderOptions(threads=1))
    closed = render(prep, "analytic", {}, RenderOptions(threads=1))
    behind = 0
    for (i, j), ref in twins.items():
        o, d = oracle.camera_ray(CAMERA, i, j)
        behind += bool(NORMALS[first(o, d)[1]] @ AXIS > 0)
        assert np.all(ref > 0)
        assert np.max(np.abs(quad.image[j, i] - ref) / ref) < 1e-6, (i, j, quad.image[j, i], ref)
        assert np.max(np.abs(closed.image[j, i] - ref) / ref) < 1e-9, (i, j, closed.image[j, i], ref)
    assert behind >= 5
    shadowed = render(prep, "quadrature", {"rtol": 1e-6}, RenderOptions(threads=1, volumetric_shadows=True))
    assert np.array_equal(shadowed.image, quad.image)
    assert shadowed.stats["inside: segments unshadowed (refractive or planar model)"] > 0


def bound_against_twin(res, twins):
    """(largest |value - twin| / bound, median bound / value) over the twin's pixels and channels; the bound finite."""
    err = np.array([np.abs(res.image[j, i] - ref) for (i, j), ref in twins.items()])
    bound = np.array([res.error_bound[j, i] for (i, j) in twins])
    assert np.all(np.isfinite(bound)), bound
    return float(np.max(err / bound)), float(np.median(bound / np.array(list(twins.values()))))


@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_the_bound_holds_and_is_not_vacuous(prep, twins, rtol):
    """quadrature's bound (the rule's, the beam's direction and irradiance, the pieces' ends: each end's span
    times the beam's integrand there) is finite on every pixel that scatters, never below the error against the
    twin (precise to about 1e-15: quadrature and analytic agree with it that closely) and at most 10 rtol of the
    value (median); analytic's closed form the same, its median at most 1e-10 (its floor, KERNEL_FLOOR, is 1e-11)."""
    worst, median = bound_against_twin(render(prep, "quadrature", {"rtol": rtol}, RenderOptions(threads=1)), twins)
    assert worst <= 1.0 and median <= 10.0 * rtol, (worst, median)
    worst, median = bound_against_twin(render(prep, "analytic", {}, RenderOptions(threads=1)), twins)
    assert worst <= 1.0 and median <= 1e-10, (worst, median)


def test_the_ends_term_covers_misplaced_ends(tmp_path, twins, monkeypatch):
    """Every triangle's edge rows moved by 1e-9 of their norm (random signs), and `face_errors` told so (its `do`):
    the pieces' ends move, analytic's closed form is some 1e-9 off the twin (far beyond the closed form's own
    rounding, ~2e-11), and the bound, whose end term takes the edges' error, still holds. Without the end term
    (interiors/rows.py `end_bounds` left out) the error is some 400 times the bound."""
    import raytrace.interiors.rows as rows
    import raytrace.media.nonconvex_directional as nd

    rng = np.random.default_rng(1)
    edges, errors = nd.edge_planes, rows.face_errors

    def moved(tris):
        e = edges(tris)
        e[:, :, 3] += 1e-9 * np.linalg.norm(e[:, :, :3], axis=2) * rng.choice([-1.0, 1.0], size=e.shape[:2])
        return e

    def told(tris, planes):
        out = errors(tris, planes)
        out[:, 3] += 1e-9
        return out

    monkeypatch.setattr(nd, "edge_planes", moved)
    monkeypatch.setattr(rows, "face_errors", told)
    res = render(scene(tmp_path), "analytic", {}, RenderOptions(threads=1))
    worst, _ = bound_against_twin(res, twins)
    off = max(np.max(np.abs(res.image[j, i] - ref) / ref) for (i, j), ref in twins.items())
    assert worst <= 1.0 and off > 1e-9, (worst, off)


def test_raymarch_and_montecarlo_converge_to_the_twin(prep, twins):
    """raymarch converges at O(h^2) (each lit piece is marched on its own: the integrand is smooth there); Monte
    Carlo is unbiased (mean squared z-score over the pixels' channels)."""
    def error(img):
        return max(np.max(np.abs(img[j, i] - r) / r) for (i, j), r in twins.items())
    errs = [error(render(prep, "raymarch", {"steps": n}, RenderOptions(threads=1)).image) for n in (4, 16)]
    assert errs[0] / errs[1] > 10.0 and errs[1] < 1e-3, errs
    res = render(prep, "montecarlo", {"samples": 64}, RenderOptions(seed=5, threads=1))
    z2 = [(res.image[j, i] - r) ** 2 / res.variance[j, i] for (i, j), r in twins.items()]
    assert 0.2 < np.mean(z2) < 3.5, z2


def test_lit_pieces_on_a_torus_match_brute_force():
    """media/nonconvex_directional.py `lit_pieces` on chords inside a coarse glass torus (240 triangles, its normals
    in either orientation) against the lit set found point by point with Moller-Trumbore: each sample is inside a
    beam's pieces exactly where the path back along it first meets that beam's triangle and the leg from there
    toward the sun meets none (samples within 1e-9 of a piece's end skipped). Both legs' tests must cut something.
    Each end inside a chord lies in one of its spans (where the true end may be, for a beam direction 1e-15 off),
    which sum to less than 1e-10 per chord."""
    import trimesh

    from raytrace.media.nonconvex_directional import face_errors, lit_pieces
    from raytrace.media.nonconvex_refraction import face_planes

    mesh = trimesh.creation.torus(1.0, 0.35, major_sections=12, minor_sections=10)
    tris = np.array(mesh.triangles, dtype=np.float64)
    tris[::3] = tris[::3, ::-1].copy()  # every third triangle turned over
    planes = face_planes(tris)
    errs = face_errors(tris, planes)
    rng = np.random.default_rng(7)
    axis = np.array([-0.4, -1.0, -0.3]) / np.linalg.norm([-0.4, -1.0, -0.3])

    def hits_of(o, d, skip=-1):
        t, u, v, det = oracle.triangle_hits(tris, o, d)
        with np.errstate(invalid="ignore"):
            t = np.where((np.abs(det) > 1e-14) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9), t, np.inf)
        if skip >= 0:
            t[skip] = np.inf
        return t

    chords = []
    for _ in range(6):
        phi, psi, r = rng.uniform(0, 2 * np.pi), rng.uniform(0, 2 * np.pi), rng.uniform(0.0, 0.3)
        centre = np.array([np.cos(phi), np.sin(phi), 0.0])
        X = centre + r * (np.cos(psi) * centre + np.array([0.0, 0.0, np.sin(psi)]))
        w = rng.normal(size=3)
        chords.append((X, w / np.linalg.norm(w)))
    origins, dirs = np.array([c[0] for c in chords]), np.array([c[1] for c in chords])
    ells = np.array([hits_of(o, w).min() for o, w in chords])
    cut = {"inside": 0, "outside": 0, "lit": 0}
    for f in range(len(tris)):
        n = planes[f, :3] * (-1.0 if planes[f, :3] @ axis > 0 else 1.0)
        d = refract(axis, n, ETA)
        if d is None or not -(axis @ n) > 0:
            continue
        (_, src, x0, x1), (owner, span) = lit_pieces(tris, planes, errs, [f], [-d], [1e-15], axis, origins, dirs, ells)
        for s in range(len(chords)):
            mine = span[owner[:, 1] == s]  # each end inside the chord lies in a span where the true end may be
            for x in np.concatenate([x0[src == s], x1[src == s]]):
                assert x in (0.0, ells[s]) or np.any((mine[:, 0] <= x) & (x <= mine[:, 1])), (f, s, x)
            assert np.sum(mine[:, 1] - mine[:, 0]) < 1e-10, (f, s, mine)
            xs = np.linspace(0.0, ells[s], 25)[1:-1]
            tf, u, v, _ = oracle.triangle_hits(np.repeat(tris[f:f + 1], len(xs), axis=0),
                                               origins[s] + xs[:, None] * dirs[s], -d)
            meets = (u >= 0) & (v >= 0) & (u + v <= 1) & (tf > 1e-9)  # the path back meets triangle f at all
            for x, m in zip(xs, meets):
                mine = (src == s) & (x0 <= x) & (x <= x1)
                if np.any((src == s) & ((np.abs(x - x0) < 1e-9) | (np.abs(x1 - x) < 1e-9))):
                    continue
                if not m:
                    assert not np.any(mine), (f, s, x)
                    continue
                X = origins[s] + x * dirs[s]
                t = hits_of(X, -d)
                lit = bool(np.isfinite(t[f]) and t[f] <= t.min())
                if np.isfinite(t[f]) and not lit:
                    cut["inside"] += 1
                if lit and np.any(np.isfinite(hits_of(X - t[f] * d, -axis, skip=f))):
                    cut["outside"] += 1
                    lit = False
                cut["lit"] += lit
                assert bool(np.any(mine)) == lit, (f, s, x)
    assert min(cut.values()) > 0, cut
