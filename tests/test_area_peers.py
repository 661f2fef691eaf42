"""Area lights against Mitsuba 3 (issue 36; docs/area_lights.md, "Against Mitsuba 3").

Default suite: `montecarlo` against `quadrature` by its own z-test on the occluded scene
(tests/data/area_peers/occluded.toml: a quad light, a plate, its penumbra on a floor, in fog).

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
quad order 12, or the luminaire's triangles split in 16), ours must agree within noise. In penumbrae
the fixed rule is a staircase of hard shadows (docs/area_lights.md): there the default rule is
outside Mitsuba's noise, a known limit marked xfail(strict) so that it flips when penumbrae are
sampled; a finer rule must come closer to Mitsuba, which shows that the difference is the rule's.
"""
from __future__ import annotations

import copy
import sys

import numpy as np
import pytest

import raytrace
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


def converged(image, finer):
    """Pixels lit by the finer rule where the default rule's image equals it to 1e-4 relative (all
    channels; Mitsuba's relative standard error is 6e-5 to 1e-2 per pixel, most above 1e-3). Pixels dark
    under both rules are left out: neither rule's points may see the light there (a penumbra)."""
    return np.all((np.abs(finer - image) <= 1e-4 * finer) & (finer > 0.0), axis=-1)


def z_scores(runs, ours, ours_variance=0.0):
    """Per pixel, on the channel sums (the channels share their random numbers), (Mitsuba's mean - ours)
    / the standard error of the difference; `ours_variance` per channel, its channels summed as fully
    correlated ((sum of standard deviations)^2: exact for montecarlo in a grey scene). Pixels where
    Mitsuba's runs all agree (its emitter seen directly, black) are compared exactly instead: z = 0
    when equal to 1e-4 relative (Mitsuba's emitter: 2e-5 from the file's value in float32 RGB), else inf."""
    runs, ours = runs.sum(-1), ours.sum(-1)
    mean, sem2 = runs.mean(0), runs.var(0, ddof=1) / len(runs)
    se = np.sqrt(sem2 + np.sqrt(ours_variance).sum(-1) ** 2)
    exact = np.abs(mean - ours) <= 1e-4 * np.abs(mean) + 1e-30
    return np.where(se > 0, (mean - ours) / np.where(se > 0, se, 1.0), np.where(exact, 0.0, np.inf))


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
    """(Mitsuba's runs of our export, our quadrature at the default rule, the converged pixels)."""
    raw, source, _ = raytrace.api.scene_dict(str(OCCLUDED))
    xml = tmp_path_factory.mktemp("occluded") / "occluded.xml"
    mitsuba_io.export(raw, xml, source, False)
    ours = occluded_image("quadrature").array
    return mitsuba_runs(mi, xml), ours, converged(ours, occluded_image("quadrature", order=12).array)


@pytest.mark.peers
def test_occluded_quad_light_agrees_with_mitsuba_where_the_rule_converged(occluded):
    """quadrature and montecarlo (64 samples, its variance added to Mitsuba's) within Mitsuba's noise
    on every pixel off the penumbrae (about 80 % of them)."""
    runs, ours, ok = occluded
    assert ok.mean() > 0.7, ok.mean()
    assert within_noise(z_scores(runs, ours)[ok], RUNS - 1)
    mc = occluded_image("montecarlo", samples=64, seed=5)
    assert within_noise(z_scores(runs, mc.array, mc.variance)[ok], RUNS - 1)


@pytest.mark.peers
@pytest.mark.xfail(strict=True, reason="the fixed 8 x 8 rule makes a penumbra of 64 hard shadows (issue 36 asks "
                                       "for stratified emitter samples there): up to 17 % from Mitsuba")
def test_occluded_penumbra_agrees_with_mitsuba(occluded):
    runs, ours, ok = occluded
    assert within_noise(z_scores(runs, ours)[~ok], RUNS - 1)


@pytest.mark.peers
def test_a_finer_rule_brings_the_penumbra_to_mitsuba(occluded):
    """Where the default rule did not converge, the 32 x 32 rule is closer to Mitsuba than the 8 x 8
    one: the mean z^2 at least 4 times smaller: the difference is the cubature's, not the scene's."""
    runs, ours, ok = occluded
    finer = occluded_image("quadrature", order=32).array
    coarse, fine = (np.mean(z_scores(runs, img)[~ok] ** 2) for img in (ours, finer))
    assert fine < coarse / 4, (coarse, fine)


@pytest.fixture(scope="module")
def cbox(mi):
    """(Mitsuba's runs of cbox-rgb.xml with max_depth = 2 at CBOX_RES^2, our quadrature of the same
    file imported, the same with the luminaire split, the converged pixels): ours at the pixel centres (spp = 1, not the file's 256)."""
    over = [f"camera.width={CBOX_RES}", f"camera.height={CBOX_RES}", "camera.spp=1"]
    raw, source, path = raytrace.api.scene_dict(str(CBOX), over)
    ours = raytrace.render(scene_from_dict(copy.deepcopy(raw), source, path), "quadrature").array
    finer = split_luminaire(raw, source, path)
    return mitsuba_runs(mi, CBOX, res=CBOX_RES, max_depth=2), ours, finer, converged(ours, finer)


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
    runs, ours, _, ok = cbox
    assert ok.mean() > 0.4, ok.mean()  # a third of the view is black (the ceiling, faces turned from the light)
    assert within_noise(z_scores(runs, ours)[ok], RUNS - 1)


@pytest.mark.peers
@pytest.mark.xfail(strict=True, reason="the luminaire's fixed rule (7 points a triangle, 14 in all) makes the boxes' "
                                       "penumbrae 14 hard shadows (issue 36 asks for stratified emitter samples): up to 41 % from "
                                       "Mitsuba")
def test_cornell_box_penumbrae_agree_with_mitsuba(cbox):
    runs, ours, _, ok = cbox
    assert within_noise(z_scores(runs, ours)[~ok], RUNS - 1)


@pytest.mark.peers
def test_a_split_luminaire_brings_the_penumbrae_to_mitsuba(cbox):
    """Where the luminaire's rule did not converge, 224 emitter points are closer to Mitsuba than 14:
    the mean z^2 at least 4 times smaller."""
    runs, ours, finer, ok = cbox
    coarse, fine = (np.mean(z_scores(runs, img)[~ok] ** 2) for img in (ours, finer))
    assert fine < coarse / 4, (coarse, fine)
