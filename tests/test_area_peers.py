"""Area lights against Mitsuba 3 (issue 36; docs/area_lights.md, "Against Mitsuba 3").

Default suite: `montecarlo` against `quadrature` by its own z-test on the occluded scene
(tests/data/area_peers/occluded.toml: a quad light, a plate, its penumbra on a floor, in fog); the
imported Cornell box's direct light against scipy's form factor where the luminaire is unoccluded.

`-m peers` (needs `pip install mitsuba`; `llvm_ad_rgb`, which needs libLLVM >= 16, for Mitsuba's
estimates at our pixel centres: benchmarks/vs_mitsuba.py's `choose_variant`): Mitsuba renders the same
scenes at our pixel centres in independent runs (its per-pixel standard error from their spread), and
ours must agree within that noise:

- the occluded scene exported by us (`volpath`, max_depth 2: single scattering with shadowed
  next-event estimation, and direct lighting of the floor and the plate);
- mitsuba-data's Cornell box (`cbox-rgb.xml`), imported by our reader and loaded by Mitsuba from the
  same file with max_depth = 2 (the emitter seen directly and one bounce: direct lighting of the
  surfaces, as ours without a medium).

Where the fixed cubature of the emitter converged (its image equals that of a finer rule to 1e-4:
quad order 12, or the luminaire's triangles split in 16) and nothing was sampled, ours must agree
within noise. The surfaces' penumbrae are sampled (docs/area_lights.md, "Penumbrae on surfaces"):
there ours, its variance added to Mitsuba's, must agree within noise too, and the rows alone (the
rule's staircase of hard shadows) must be beyond Mitsuba's noise there (on the occluded quad light,
those of the former fixed 8 x 8 rule at least 4 times farther than the samples), which shows that the
difference Mitsuba sees there is the rule's. `analytic` at precision 1e-1 (the cheapest setting benchmarks/area_peers.py times) must
be within 1e-2 mean relative error of Mitsuba's mean on the occluded scene. In the Cornell box the
faces whose own plane cuts the luminaire (its horizon, not an occluder) are sampled as penumbrae; the
pixels left to the rule agree within noise.
"""
from __future__ import annotations

import copy
import sys

import numpy as np
import pytest
from scipy import stats

import raytrace
from raytrace import shading
from raytrace.io import mitsuba as mitsuba_io
from raytrace.lights import quad
from raytrace.scene.format import scene_from_dict

from .conftest import ROOT

OCCLUDED = ROOT / "tests" / "data" / "area_peers" / "occluded.toml"
CBOX = ROOT / "tests" / "data" / "corpus" / "mitsuba-data" / "scenes" / "cbox" / "cbox-rgb.xml"
CBOX_RES = 32
RUNS, SPP = 24, 2048  # Mitsuba: independent runs (seeds) of SPP samples per pixel centre


def occluded_image(method, order=None, **params):
    """Our render of the occluded scene (volumetric shadows on); `order` sets the quad rule's order."""
    saved = quad.ORDER
    quad.ORDER = order or saved
    try:
        return raytrace.render(str(OCCLUDED), method, volumetric_shadows=True, **params)
    finally:
        quad.ORDER = saved


def converged(image, finer, variance):
    """Pixels lit by the finer rule where the default rule's image equals it to 1e-4 relative (all
    channels; Mitsuba's relative standard error here is 6e-5 to 1e-2 per pixel) and nothing was
    sampled (`variance` 0: no penumbra on the surface seen, shading.penumbra; None: a render that
    sampled nothing). Pixels dark under both rules are left out: neither rule's points may see the
    light there (a penumbra)."""
    unsampled = True if variance is None else variance == 0.0
    return np.all((np.abs(finer - image) <= 1e-4 * finer) & (finer > 0.0) & unsampled, axis=-1)


def z_scores(runs, ours, ours_variance=0.0):
    """Per pixel, on the channel sums (the channels share their random numbers), (Mitsuba's mean - ours)
    / the standard error of the difference; `ours_variance` per channel, its channels summed as fully
    correlated ((sum of standard deviations)^2: exact for montecarlo in a grey scene). Pixels where
    Mitsuba's runs all agree to float32 rounding (its emitter seen directly, black; its LLVM backend's
    sums may differ by an ulp from run to run) and ours has no variance are compared exactly instead:
    z = 0 when equal to 1e-4 relative (Mitsuba's emitter: 2e-5 from the file's value in float32 RGB),
    else inf."""
    ours_sd = np.sqrt(np.broadcast_to(ours_variance, ours.shape)).sum(-1)
    runs, ours = runs.sum(-1), ours.sum(-1)
    mean, sem2 = runs.mean(0), runs.var(0, ddof=1) / len(runs)
    se = np.sqrt(sem2 + ours_sd**2)
    agree = (np.ptp(runs, axis=0) <= 4 * np.finfo(np.float32).eps * np.abs(mean)) & (ours_sd == 0.0)
    exact = np.abs(mean - ours) <= 1e-4 * np.abs(mean) + 1e-30
    return np.where(agree, np.where(exact, 0.0, np.inf), (mean - ours) / np.where(se > 0, se, 1.0))


def within_noise(z, dof):
    """z is Student's t with `dof` degrees of freedom for an unbiased match (mean square
    dof / (dof - 2)): the mean square within 1.5 times that, at most 1 % of the values beyond 4."""
    return np.mean(z**2) < 1.5 * dof / (dof - 2) and np.mean(np.abs(z) > 4) <= 0.01


def test_montecarlo_against_quadrature_on_the_occluded_scene():
    """montecarlo (64 distance samples, the same emitter rows) is unbiased against quadrature's value
    of the rows, penumbra and shadow volume included: mean z^2 of the 32 x 24 x 3 values below 1.3,
    none beyond 5 sigma."""
    ref = occluded_image("quadrature", rtol=1e-10).array
    mc = occluded_image("montecarlo", samples=64, seed=3)
    z = (mc.array - ref) / np.sqrt(mc.variance)
    assert np.mean(z**2) < 1.3 and np.abs(z).max() < 5.0, (np.mean(z**2), np.abs(z).max())


def cbox_dict():
    """(raw, source, path) of cbox-rgb.xml through our reader at CBOX_RES^2 pixel centres (spp 1, not
    the file's 256)."""
    return raytrace.api.scene_dict(str(CBOX), [f"camera.width={CBOX_RES}", f"camera.height={CBOX_RES}", "camera.spp=1"])


def test_cornell_box_direct_light_against_scipy():
    """The imported Cornell box without Mitsuba: at every pixel whose ray (trimesh's, from our camera)
    ends on a flat surface (the floor, the back and green walls, the boxes: not the red wall, whose
    two triangles are not coplanar and get smoothed normals) that sees the whole luminaire (shadow
    rays to a 9 x 9 grid on it reach it: 394 of the 1024 pixels), our radiance equals
    rho / pi * L * the form factor of the luminaire's rectangle integrated by scipy from the
    geometry: within 1e-4 (the 7-point rule's error nearer the light, measured 4.2e-5), the median
    pixel within 1e-5."""
    import trimesh
    from scipy import integrate

    from raytrace.camera import generate_rays

    raw, source, path = cbox_dict()
    scene = scene_from_dict(copy.deepcopy(raw), source, path)
    ours = raytrace.render(scene, "quadrature").array.reshape(-1, 3)
    o, d = generate_rays(scene.camera)
    shapes = raw["shape"]
    meshes = [trimesh.Trimesh(np.asarray(s["vertices"]), np.asarray(s["faces"]), process=False) for s in shapes]
    whole = trimesh.util.concatenate(meshes)
    owner = np.repeat(np.arange(len(shapes)), [len(m.faces) for m in meshes])
    (lamp,) = [i for i, s in enumerate(shapes) if "emission" in s]
    corners = np.asarray(shapes[lamp]["vertices"])
    (x0, y, z0), (x1, _, z1) = corners.min(0), corners.max(0)
    assert np.all(corners[:, 1] == y)
    radiance = np.asarray(shapes[lamp]["emission"])
    u = np.linspace(0.0, 1.0, 9)
    grid = np.array([[x0 + a * (x1 - x0), y, z0 + b * (z1 - z0)] for a in u for b in u])
    def flat(s, m):  # every face's vertex normals along the face's own normal
        nv = np.asarray(s["normals"], float)[m.faces]
        return np.allclose(np.abs(np.sum(nv * m.face_normals[:, None], -1)) / np.linalg.norm(nv, axis=-1), 1.0, rtol=0,
                           atol=1e-12)

    flat = [i for i, (s, m) in enumerate(zip(shapes, meshes)) if i != lamp and flat(s, m)]
    errors = []
    for p, k, f in zip(*whole.ray.intersects_location(o, d, multiple_hits=False)):
        n = whole.face_normals[f] * -np.sign(whole.face_normals[f] @ d[k])
        if owner[f] not in flat or not np.all(((grid - p) @ n > 0) & (grid[:, 1] > p[1])):
            continue
        q = p + 1e-3 * n  # (the scene is 559 across)
        to = grid - q
        hit, ray, _ = whole.ray.intersects_location(np.repeat(q[None], len(grid), 0), to, multiple_hits=False)
        if np.any(np.linalg.norm(hit - q, axis=1) < np.linalg.norm(to[ray], axis=1) * (1 - 1e-9)):
            continue  # something between the point and the luminaire

        def integrand(z, x, p=p, n=n):
            v = np.array([x, y, z]) - p
            r2 = v @ v
            return max(n @ v, 0.0) * max(v[1], 0.0) / r2**2  # cos at the point, cos at the light, / r^2

        form = integrate.dblquad(integrand, x0, x1, z0, z1, epsabs=0, epsrel=1e-10)[0]
        want = np.asarray(shapes[owner[f]]["reflectance"]) / np.pi * radiance * form
        errors.append(np.abs(ours[k] / want - 1).max())
    assert len(errors) > 300, len(errors)
    assert max(errors) <= 1e-4 and np.median(errors) <= 1e-5, (max(errors), np.median(errors))


# ----------------------------------------------------------------------------------------- Mitsuba 3 itself

@pytest.fixture(scope="module")
def mi():
    pytest.importorskip("mitsuba")
    sys.path.insert(0, str(ROOT))
    from benchmarks.vs_mitsuba import choose_variant

    import drjit
    import mitsuba

    variant, why = choose_variant("auto")
    if variant != "llvm_ad_rgb":
        pytest.skip(f"Mitsuba at our pixel centres needs llvm_ad_rgb: {why}")
    mitsuba.set_variant(variant)
    return mitsuba, drjit


def mitsuba_runs(mi, path, **params):
    """RUNS independent estimates (RUNS, H, W, 3) of Mitsuba's radiance at our pixel centres."""
    from benchmarks.vs_mitsuba import Mitsuba

    m = Mitsuba.from_file(*mi, path, **params)
    return np.array([m.centres(SPP, 1000 + k) for k in range(RUNS)])


@pytest.fixture(scope="module")
def occluded(mi, tmp_path_factory):
    """(Mitsuba's runs of our export, our quadrature at the default rule, its variance (the surface's
    penumbrae sampled), the converged pixels)."""
    raw, source, _ = raytrace.api.scene_dict(str(OCCLUDED))
    xml = tmp_path_factory.mktemp("occluded") / "occluded.xml"
    mitsuba_io.export(raw, xml, source, False)
    ours = occluded_image("quadrature")
    return (mitsuba_runs(mi, xml), ours.array, ours.variance,
            converged(ours.array, occluded_image("quadrature", order=12).array, ours.variance))


@pytest.mark.peers
def test_occluded_quad_light_agrees_with_mitsuba_where_the_rule_converged(occluded):
    """quadrature and montecarlo (64 samples, its variance added to Mitsuba's) within Mitsuba's noise
    on every pixel off the penumbrae (about 80 % of them)."""
    runs, ours, _, ok = occluded
    assert ok.mean() > 0.7, ok.mean()
    assert within_noise(z_scores(runs, ours)[ok], RUNS - 1)
    mc = occluded_image("montecarlo", samples=64, seed=5)
    assert within_noise(z_scores(runs, mc.array, mc.variance)[ok], RUNS - 1)


@pytest.mark.peers
def test_occluded_penumbra_agrees_with_mitsuba(occluded):
    """Every other pixel (the floor's sampled penumbra, its variance added to Mitsuba's, and the rays
    through the fog near the plate's shadow) within Mitsuba's noise."""
    runs, ours, variance, ok = occluded
    assert within_noise(z_scores(runs, ours, variance)[~ok], RUNS - 1)


def occluders_only(render):
    """`render()` with the emitters sampled only where occluders cut them (not where a point's horizon does)."""
    saved = shading._horizon_cuts
    shading._horizon_cuts = lambda above, probes: np.zeros(len(above), dtype=bool)
    try:
        return render()
    finally:
        shading._horizon_cuts = saved


def rows_alone(render):
    """`render()` with the emitters' rows everywhere (no penumbra sampled: shading._cut finds none)."""
    saved = shading._cut
    shading._cut = lambda *args: np.zeros(len(args[1]), dtype=bool)
    try:
        return render()
    finally:
        shading._cut = saved


def sampling_matters(runs, ours, variance, rows, by_occluders, ratio=4.0):
    """On the pixels sampled where occluders cut the emitter (`by_occluders`: the variance of a render
    with the horizon's cuts left out): the rows alone beyond Mitsuba's noise (their mean z^2 above the
    chi-square's 0.999 quantile over its degrees of freedom) and `ratio` times farther from it (mean
    z^2) than the samples (None: not asked): the difference Mitsuba sees there is the rule's. (Pixels
    whose horizon cuts the emitter are sampled too; the test of the pixels left to the rule covers them.)"""
    sampled = np.any(by_occluders > 0.0, axis=-1)
    assert sampled.sum() > 50, sampled.sum()
    samples, rule = (np.mean(z_scores(runs, img, var)[sampled] ** 2) for img, var in ((ours, variance), (rows, 0.0)))
    k = np.count_nonzero(sampled) * ours.shape[-1]
    assert rule > stats.chi2.ppf(0.999, k) / k and (ratio is None or rule > ratio * samples), (samples, rule)


def fixed_rule(render, order=8):
    """`render()` with the quad light's rule fixed at `order` x `order` nodes (the pilot's ladder narrowed)."""
    from raytrace.lights import cubature

    saved = cubature.AREA_LADDER
    cubature.AREA_LADDER = (order,)
    try:
        return render()
    finally:
        cubature.AREA_LADDER = saved


@pytest.mark.peers
def test_sampling_brings_the_penumbra_to_mitsuba(occluded):
    """The rows alone at the pilot's order (1024 nodes at the default rtol) beyond Mitsuba's noise, and
    those of the former fixed 8 x 8 rule at least 4 times farther from it than the samples. (At 1024
    nodes the rows' mean z^2 is about 2.9: near enough that even exact samples, whose mean z^2 is
    Mitsuba's noise alone, about 1.1, could not be 4 times nearer.)"""
    runs, ours, variance, _ = occluded
    by_occluders = occluders_only(lambda: occluded_image("quadrature").variance)
    sampling_matters(runs, ours, variance, rows_alone(lambda: occluded_image("quadrature").array), by_occluders,
                     ratio=None)
    sampling_matters(runs, ours, variance, fixed_rule(lambda: rows_alone(lambda: occluded_image("quadrature").array)),
                     by_occluders)


@pytest.mark.peers
def test_analytic_at_its_loosest_timed_precision_against_mitsuba(occluded):
    """`analytic` at precision 1e-1 (the cheapest setting benchmarks/area_peers.py times): within 1e-2
    mean relative error (vs_mitsuba.mre) of Mitsuba's mean over its runs, which itself carries about
    6e-3 (E|N(0, se)| / value, from the runs' spread; asserted below 8e-3); the air's penumbrae, sampled
    at 4 x 4 strata there, within Mitsuba's noise with our variance added."""
    from benchmarks.vs_mitsuba import mre

    runs = occluded[0]
    mean, se = runs.mean(0), runs.std(0, ddof=1) / np.sqrt(len(runs))
    mask = mean > 1e-3 * mean.max()
    assert np.mean(np.sqrt(2.0 / np.pi) * se[mask] / mean[mask]) < 8e-3
    img = occluded_image("analytic", precision=1e-1)
    assert mre(img.array, mean) < 1e-2, mre(img.array, mean)
    sampled = np.any(img.variance > 0.0, axis=-1)
    assert sampled.sum() > 50 and within_noise(z_scores(runs, img.array, img.variance)[sampled], RUNS - 1)


@pytest.fixture(scope="module")
def cbox(mi):
    """(Mitsuba's runs of cbox-rgb.xml with max_depth = 2 at CBOX_RES^2, our quadrature of the same
    file imported, its variance (the penumbrae sampled), the same with the luminaire split, the
    converged pixels): ours at the pixel centres (spp = 1, not the file's 256)."""
    raw, source, path = cbox_dict()
    ours = raytrace.render(scene_from_dict(copy.deepcopy(raw), source, path), "quadrature")
    finer = split_luminaire(raw, source, path)
    return (mitsuba_runs(mi, CBOX, res=CBOX_RES, max_depth=2), ours.array, ours.variance, finer,
            converged(ours.array, finer, ours.variance))


def split_luminaire(raw, source, path):
    """Our image with the luminaire's two triangles split in 16 each (trimesh's midpoint
    subdivision, twice): 224 emitter points instead of 14."""
    import trimesh

    (lamp,) = [s for s in raw["shape"] if "emission" in s]
    v, f = np.asarray(lamp["vertices"], float), np.asarray(lamp["faces"])
    for _ in range(2):
        v, f = trimesh.remesh.subdivide(v, f)
    lamp.update(vertices=v.tolist(), faces=f.tolist(), normals=[lamp["normals"][0]] * len(v))
    return raytrace.render(scene_from_dict(raw, source, path), "quadrature").array


@pytest.mark.peers
def test_cornell_box_agrees_with_mitsuba_where_the_rule_converged(cbox):
    """The luminaire seen directly equals Mitsuba's radiance (float32) and the surfaces off the boxes'
    penumbrae agree within Mitsuba's noise."""
    runs, ours, _, _, ok = cbox
    assert ok.mean() > 0.4, ok.mean()  # a third of the view is black (the ceiling, faces turned from the light)
    assert within_noise(z_scores(runs, ours)[ok], RUNS - 1)


@pytest.mark.peers
def test_cornell_box_penumbrae_agree_with_mitsuba(cbox):
    """The sampled pixels (the boxes' penumbrae, the faces whose horizon cuts the luminaire), their
    variance added to Mitsuba's, within its noise; the rows alone on the occluders' penumbrae beyond it."""
    runs, ours, variance, _, _ = cbox
    assert within_noise(z_scores(runs, ours, variance)[np.any(variance > 0.0, axis=-1)], RUNS - 1)
    raw, source, path = cbox_dict()
    render = lambda: raytrace.render(scene_from_dict(raw, source, path), "quadrature")  # noqa: E731
    # the pilot gives the luminaire's rows the default rtol's order, so the rows alone are near: only beyond noise
    sampling_matters(runs, ours, variance, rows_alone(lambda: render().array), occluders_only(lambda: render().variance),
                     ratio=None)


@pytest.mark.peers
def test_cornell_box_pixels_left_to_the_rule_agree_with_mitsuba(cbox):
    runs, ours, variance, _, ok = cbox
    assert within_noise(z_scores(runs, ours)[~ok & np.all(variance == 0.0, axis=-1)], RUNS - 1)
