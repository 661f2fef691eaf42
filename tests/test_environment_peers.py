"""The environment light against Mitsuba 3 (issue 36; docs/environment.md, "Against Mitsuba 3").

All `-m peers` (needs `pip install mitsuba` and its `llvm_ad_rgb` variant; skipped cleanly without):
Mitsuba renders our export of tests/data/env_peers/fog_box.toml (`volpath`, max_depth 2: single
scattering with shadowed next-event estimation, direct lighting of the surfaces) at our pixel centres
in RUNS independent runs, and ours must agree within that noise (tests/test_area_peers.py's z-test).
The scene: a constant environment over a vacuum, a closed box of homogeneous fog (an index-matched
interior) on a ground quad, under an opaque plate.

Our 64 fixed directions make a shadow cast by the sky a sum of 64 hard shadows: where the default
image differs from FINE directions' it is outside Mitsuba's noise, a known limit marked
xfail(strict); FINE directions come closer to Mitsuba. The fog inside the box under the plate stays
2-4 % below Mitsuba at any count (a finding for the lead, marked xfail(strict)).

Height fog is not compared: Mitsuba 3 has no exponential height fog, and its `heterogeneous` medium is
bounded by its shape while ours extends to infinity sideways and upward (docs/environment.md).
"""
from __future__ import annotations

import copy

import numpy as np
import pytest

import raytrace
from raytrace.io import mitsuba as mitsuba_io
from raytrace.lights import environment
from raytrace.scene.format import scene_from_dict

from .conftest import ROOT
from .test_area_peers import RUNS, converged, mi, mitsuba_runs, within_noise, z_scores  # noqa: F401 (mi: a fixture)

FOG_BOX = ROOT / "tests" / "data" / "env_peers" / "fog_box.toml"
FINE = 4096  # directions of the finer lattice (its image within 0.1 % of 1024's)


def ours(method="quadrature", count=None, **params):
    """Our render of the fog box scene (volumetric shadows on) with `count` directions (default COUNT)."""
    saved = environment.COUNT
    environment.COUNT = count or saved
    try:
        return raytrace.render(str(FOG_BOX), method, volumetric_shadows=True, **params)
    finally:
        environment.COUNT = saved


@pytest.fixture(scope="module")
def fog_box(mi, tmp_path_factory):  # noqa: F811 (the fixture)
    """(the exported XML, Mitsuba's runs of it, our quadrature at COUNT, at FINE, the pixels where they agree)."""
    raw, source, _ = raytrace.api.scene_dict(str(FOG_BOX))
    xml = tmp_path_factory.mktemp("fog_box") / "fog_box.xml"
    mitsuba_io.export(copy.deepcopy(raw), xml, source, False)
    default, fine = ours().array, ours(count=FINE).array
    return xml.read_text(), mitsuba_runs(mi, xml), default, fine, converged(default, fine)


@pytest.mark.peers
def test_the_export_carries_the_constant_emitter_and_the_interior(fog_box):
    """The constant emitter with our radiance; the box an index-matched (null) shape holding the fog
    (sigma_t 0.8, albedo 0.75, isotropic) as its interior medium; the sensor in vacuum."""
    xml = fog_box[0]
    assert '<emitter type="constant">\n    <rgb name="radiance" value="0.2, 0.3, 0.5" />' in xml
    assert ('<bsdf type="null" />\n    <medium type="homogeneous" name="interior">\n'
            '      <rgb name="sigma_t" value="0.8, 0.8, 0.8" />') in xml
    assert 'name="albedo" value="0.7499999999999999' in xml and '<phase type="isotropic" />' in xml
    assert xml.count("<medium") == 1


@pytest.mark.peers
def test_pixels_the_lattice_resolves_agree_with_mitsuba(fog_box):
    """Where 64 directions give FINE's image to 1e-4 (the sky, the plate's top, the open ground: 47 % of
    the pixels), quadrature and montecarlo (16 samples, its variance added) are within Mitsuba's noise."""
    _, runs, default, _, ok = fog_box
    assert ok.mean() > 0.4, ok.mean()
    assert within_noise(z_scores(runs, default)[ok], RUNS - 1)
    mc = ours("montecarlo", samples=16, seed=5)
    assert within_noise(z_scores(runs, mc.array, mc.variance)[ok], RUNS - 1)


@pytest.mark.peers
@pytest.mark.xfail(strict=True, reason="64 fixed directions make the plate's and the box's sky shadows 64 hard "
                                       "shadows (docs/environment.md): up to 15 % from Mitsuba")
def test_sky_shadows_agree_with_mitsuba(fog_box):
    _, runs, default, _, ok = fog_box
    assert within_noise(z_scores(runs, default)[~ok], RUNS - 1)


@pytest.mark.peers
def test_more_directions_bring_the_sky_shadows_to_mitsuba(fog_box):
    """Where 64 directions did not converge, FINE directions are closer to Mitsuba: the mean z^2 at
    least 4 times smaller (the difference is the lattice's)."""
    _, runs, default, fine, ok = fog_box
    coarse, finer = (np.mean(z_scores(runs, img)[~ok] ** 2) for img in (default, fine))
    assert finer < coarse / 4, (coarse, finer)


@pytest.mark.peers
@pytest.mark.xfail(strict=True, reason="the fog inside the box under the plate is 2-4 % below Mitsuba with 1024 or "
                                       "4096 directions, in quadrature, raymarch and montecarlo alike (without the "
                                       "plate the scene agrees): not the lattice, cause not found")
def test_sky_shadows_agree_with_mitsuba_at_fine_directions(fog_box):
    _, runs, _, fine, _ = fog_box
    assert within_noise(z_scores(runs, fine), RUNS - 1)


@pytest.mark.peers
def test_without_the_plate_the_fog_box_agrees_with_mitsuba(mi, tmp_path):  # noqa: F811 (the fixture)
    """The same scene without the plate at 1024 directions: every pixel within Mitsuba's noise (so the
    previous test's residual needs the plate's shadow on the fog)."""
    raw, source, path = raytrace.api.scene_dict(str(FOG_BOX))
    raw["shape"] = raw["shape"][:2]
    mitsuba_io.export(copy.deepcopy(raw), tmp_path / "open.xml", source, False)
    saved, environment.COUNT = environment.COUNT, 1024
    try:
        image = raytrace.render(scene_from_dict(raw, source, path), "quadrature", volumetric_shadows=True).array
    finally:
        environment.COUNT = saved
    assert within_noise(z_scores(mitsuba_runs(mi, tmp_path / "open.xml"), image), RUNS - 1)
