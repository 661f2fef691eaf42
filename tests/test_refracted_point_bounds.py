"""quadrature's error bound for point and spot light refracted into a convex refractive shape (media/slab.py
`faces_quadrature`, media/fermat_rounding.py; docs/error_bounds.md, "Point and spot light in
refractive shapes"): the water box (ior 1.33) under a lamp above its top and beyond a side, and the
glass block (ior 1.5) under a spot from the side, seen through a face the light is behind, against
the twin of tests/test_refracted_point_light.py (Fermat's path by brentq, Fresnel by its formula, the
ray tube's irradiance, scipy quad between the bisected switches of the exact face test).

Until this change the bound was inf on every pixel of both images; the breaks where a refraction
point crosses a face's edge were taken only where the sign differed at the segment's ends, and a
spot's cone crossings only between 64 samples, so the glass block lost the +y face's switches
where its refraction point leaves and re-enters the face, and a cone crossing in the last half
sample (`test_every_switch_is_a_break`; quadrature at rtol 1e-6 was 7e-7 off there, now 3e-12)."""

import numpy as np
import pytest

from raytrace.media import slab
from raytrace.media.fermat_rounding import term_rounding

from . import oracle
from .test_refracted_point_light import CAMERA, FACES, GLASS, HI, LO, WATER, camera_entry, fermat, image, on_face, \
    spot_terms, switches, twin_pixel

PLANES = np.array([[*n, 1.0] for n in FACES])


@pytest.fixture(scope="module", params=[WATER, GLASS], ids=["water_lamp_above", "glass_spot_beside"])
def case(request):
    scene = request.param
    twin = np.array([[twin_pixel(scene, i, j) for i in range(CAMERA["width"])] for j in range(CAMERA["height"])])
    return scene, twin


def assert_bound(res, twin, rtol):
    """The render's bound is finite on every pixel, never below its error against the twin, and its
    median at most 10 rtol of the value (over the pixels the twin lights)."""
    bound = res.error_bound
    assert np.all(np.isfinite(bound))
    err = np.abs(res.image - twin)
    assert np.all(err <= bound), np.max(err / bound)
    lit = twin > 0.0
    assert np.median(bound[lit] / twin[lit]) <= 10.0 * rtol, np.median(bound[lit] / twin[lit])


@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_the_bound_holds_and_is_not_vacuous(case, rtol):
    """Finite on every pixel (inf before), never below the error, and its median at most 10 rtol of
    the value (every pixel is lit)."""
    scene, twin = case
    assert np.all(twin > 0.0)
    assert_bound(image(scene, "quadrature", {"rtol": rtol}), twin, rtol)


def test_the_bound_is_close_enough_to_fail(case):
    """At rtol 1e-12 the error left is the face test's own tolerance (a refraction point within 1e-12
    of the scene from an edge counts as on the face), which the bound carries as the breaks'
    location error: on the pixels whose refraction points cross an edge the error reaches a tenth
    of the bound, so a bound ten times too small fails the check above."""
    scene, twin = case
    res = image(scene, "quadrature", {"rtol": 1e-12})
    ratio = np.abs(res.image - twin) / res.error_bound
    assert np.all(ratio <= 1.0)
    assert np.max(ratio) > 0.02, np.max(ratio)


def _segment(scene, i, j):
    """The geo row, face rows (`refracting_faces`) and length of pixel (i, j)'s inside segment."""
    eta = scene["shape"][0]["interior"]["ior"]
    _, p, w, _, _ = camera_entry(scene, i, j, eta)
    ell, _ = oracle.box_exit(p, w, LO, HI)
    light = scene["light"][0]
    L = np.array(light["position"], float)
    geo = np.zeros(slab.GEO_COLUMNS)
    geo[:3], geo[3:6], geo[6:9], geo[14:17] = p, w, L, (0.0, 0.0, 1.0)
    spot = spot_terms(light)
    geo[9:12], geo[12:14] = (spot[0], spot[1:]) if spot else (0.0, (-3.0, -2.0))
    n = geo[14:17]
    a, hl = -w @ n, (L - p) @ n
    lh = (L - p) - hl * n
    geos = np.ascontiguousarray(geo[None, :])
    faces, m, terms = slab._faces(0, geos, PLANES, np.array([a]), np.array([hl]), np.array([(w + a * n) @ lh]),
                                  np.array([lh @ lh]), -1)
    return geo, faces[:m], terms, ell, eta


@pytest.mark.parametrize("scene", [WATER, GLASS], ids=["water_lamp_above", "glass_spot_beside"])
def test_every_switch_is_a_break(scene):
    """On every pixel's segment, each x where the twin's exact face test or a cone level switches
    (bisected between 500 samples) is within 1e-9 of a break of `edge_breaks` or `refracted_cuts`."""
    L = np.array(scene["light"][0]["position"], float)
    spot = spot_terms(scene["light"][0])
    found = 0
    for i in range(CAMERA["width"]):
        for j in range(CAMERA["height"]):
            geo, faces, terms, ell, eta = _segment(scene, i, j)
            p, w = geo[:3], geo[3:6]
            for row in faces:
                n = PLANES[int(row[17]), :3]
                cuts = np.empty(64)
                k = slab.edge_breaks(row, PLANES, eta, ell, cuts)
                if spot:
                    k += slab.refracted_cuts(row[0], row[3], row[4], row[1], row[2], eta, row[5], row[6], row[7],
                                             terms[3], terms[4], ell, cuts[k:])
                twin = switches(p, w, ell, lambda x: on_face(fermat(p + x * w, L, n, 1.0, eta)[0], n), 500)
                if spot:
                    def side(x):
                        R = fermat(p + x * w, L, n, 1.0, eta)[0]
                        c = (R - L) @ spot[0] / np.linalg.norm(R - L)
                        return c > spot[1], c > spot[2]
                    twin += switches(p, w, ell, side, 500)
                for x in twin:
                    assert np.min(np.abs(cuts[:k] - x)) < 1e-9, (i, j, row[17], x, cuts[:k])
                found += len(twin)
    assert found >= 3


def test_fresnel_transmittance_log_slope():
    """|d log T / d log cos t1| <= 2 for eta > 1 (fermat_rounding.py takes Fresnel's T's relative error as twice
    its cosine's): on a dense grid it is at most 1.001."""
    c = np.geomspace(1e-8, 1.0, 100001)
    for eta in (1.0001, 1.01, 1.1, 1.33, 1.5, 2.0, 3.0, 10.0):
        t = 1.0 - np.array([slab.fresnel(x, eta) for x in c[::50]])
        slope = np.abs(np.diff(np.log(t)) / np.diff(np.log(c[::50])))
        assert np.max(slope) <= 1.001, (eta, np.max(slope))


@pytest.mark.parametrize("scene", [WATER, GLASS], ids=["water_lamp_above", "glass_spot_beside"])
def test_term_rounding_covers_the_planes_errors(scene):
    """With planes 1e-9 off their faces (dn on each normal component, dc on the offsets; far above the
    rounding), a face's term moved by random such errors stays within the relative bound of
    `term_rounding` (first order, doubled), at nodes away from the edges."""
    rng = np.random.default_rng(3)
    dn = dc = 1e-9
    ph = slab.phase_condition(1, scene["shape"][0]["interior"]["phase"]["g"])
    kt, ks, kt_out = 0.7, 0.5, 0.05
    checked, worst = 0, 0.0
    for i, j in ((1, 1), (3, 2), (4, 4), (2, 3)):
        geo, faces, terms, ell, eta = _segment(scene, i, j)
        mags = (np.linalg.norm(geo[:3]), np.linalg.norm(geo[6:9]), np.linalg.norm(geo[6:9] - geo[:3]),
                np.linalg.norm(geo[:3]) + ell + np.linalg.norm(geo[6:9]) + 1.0)
        entry = slab.entry_face(geo, PLANES)
        for x in rng.uniform(0.05, ell - 0.05, 6):
            for row in faces:
                f = int(row[17])
                if f == entry:
                    continue
                term, rho, r, on = slab._face_term(x, row, PLANES, eta, kt, ks, 1, 0.3, kt_out, -3.0, -2.0, 0)
                if not on or term == 0.0:
                    continue
                eps, _ = term_rounding(x, row[0], row[1], row[2], row[4], rho, r, eta, kt, kt_out, ph, dn, dc, mags,
                                       False)
                for _ in range(20):
                    planes = PLANES.copy()
                    planes[f, :3] += rng.uniform(-0.5 * dn, 0.5 * dn, 3)
                    planes[f, 3] += rng.uniform(-0.5 * dc, 0.5 * dc)
                    planes[f] /= np.linalg.norm(planes[f, :3])  # a unit normal within dn of the face's
                    moved = np.empty((6, slab.FACE_COLUMNS))
                    cnt = slab.refracting_faces(geo, planes, 0.0, 0.0, 0.0, 0.0, slab.NO_SPOT, moved)
                    mrow = next(moved[k] for k in range(cnt) if moved[k, 17] == f)
                    other = slab._face_term(x, mrow, PLANES, eta, kt, ks, 1, 0.3, kt_out, -3.0, -2.0, 0)
                    if not other[3]:
                        continue  # moved across an edge: a break, not this term's rounding
                    rel = abs(other[0] - term) / term
                    assert rel <= eps, (rel, eps)
                    worst = max(worst, rel / eps)
                    checked += 1
    assert checked >= 50 and worst > 1e-3, (checked, worst)
