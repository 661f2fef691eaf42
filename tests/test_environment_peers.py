"""The environment light against Mitsuba 3 (issue 36; docs/environment.md, "Against Mitsuba 3").

All `-m peers` (needs `pip install mitsuba` and its `llvm_ad_rgb` variant; skipped cleanly without):
Mitsuba renders our export (`volpath`, max_depth 2: single scattering with shadowed next-event
estimation, direct lighting of the surfaces) at our pixel centres in RUNS independent runs of SPP
samples, and ours must agree within that noise (tests/test_area_peers.py's z-test).

- tests/data/env_peers/fog_box.toml: a constant environment over a vacuum, a closed box of homogeneous
  fog (an index-matched interior) on a ground quad under an opaque plate;
- the same scene under a 16 x 8 equirectangular map written here (a sky gradient, one bright sun
  texel, a dim ground), the plate black (see below). Mitsuba's `envmap` interpolates its bitmap
  bilinearly where ours holds each texel constant, so Mitsuba gets our map repeated 64 x 64 (nearest):
  the same function except within 1/128 of a texel of the texels' edges.

Our 64 directions a pixel sample make the shadows cast by the sky sums of 64 hard shadows, random from
seed to seed: each comparison adds our variance (the groups' spread) to Mitsuba's, and at 64 directions
compares the mean of SEEDS renders (their variance SEEDS degrees of freedom); FINE directions come closer
to Mitsuba (z without our variance). Findings, each an xfail(strict): with a grey plate Mitsuba's volpath
at max_depth 2 adds light reflected by the plate to the fog box's pixels (a black plate removes it: every
pixel agrees, at 64 and at FINEST directions); Mitsuba does not read a nearest map as we do (it
interpolates; exported with --approximate). With filter = "mitsuba" (its own interpolation) the 16 x 8 map
itself is exported exactly and every pixel agrees at FINE directions. The exporter finds the map beside
the scene file from any working folder.

Height fog is not compared: Mitsuba 3 has no exponential height fog, and a `heterogeneous` medium's grid
is bounded by its shape while ours extends to infinity sideways and upward (docs/environment.md).
"""
from __future__ import annotations

import contextlib
import copy

import numpy as np
import pytest

import raytrace
from raytrace.io import mitsuba as mitsuba_io
from raytrace.lights import environment
from raytrace.output.film import write_exr
from raytrace.scene.format import scene_from_dict

from .conftest import ROOT, to_toml
from .test_area_peers import RUNS, converged, mi, mitsuba_runs, within_noise, z_scores  # noqa: F401 (mi: a fixture)

FOG_BOX = ROOT / "tests" / "data" / "env_peers" / "fog_box.toml"
FINE = 4096  # directions of the finer lattice
FINEST = 16384  # the black plate's (at 4096 our error is most of the mean z^2 without our variance)
SEEDS = 16  # renders averaged at 64 directions
REPEAT = 64  # Mitsuba's copy of the map: each texel repeated REPEAT x REPEAT


def fog_box(plate=0.5, light=None, folder=None):
    """(raw, source, path) of the fog box scene with the plate's reflectance and, given, another light
    (the scene written to `folder`, where its map lies)."""
    raw, source, path = raytrace.api.scene_dict(str(FOG_BOX))
    raw["shape"][2]["reflectance"] = plate
    if light is None:
        return raw, source, path
    raw["light"] = [light]
    (folder / "scene.toml").write_text(to_toml(raw))
    return raytrace.api.scene_dict(str(folder / "scene.toml"))


def ours(scene, method="quadrature", count=None, seeds=1, seed=0, **params):
    """(image, variance): our renders (volumetric shadows on) of (raw, source, path) with `count` directions a
    pixel sample (default COUNT) and the seeds seed ... seed + seeds - 1: their mean and its variance (the
    renders' summed / seeds^2)."""
    saved = environment.COUNT
    environment.COUNT = count or saved
    try:
        imgs = [raytrace.render(scene_from_dict(copy.deepcopy(scene[0]), *scene[1:]), method, volumetric_shadows=True,
                                seed=k, **params) for k in range(seed, seed + seeds)]
    finally:
        environment.COUNT = saved
    return np.mean([i.array for i in imgs], axis=0), np.sum([i.variance for i in imgs], axis=0) / seeds**2


def export(scene, xml, approximate=False):
    """Our Mitsuba export of (raw, source, path) to `xml`, run from the scene's folder (see
    test_an_export_from_another_folder_finds_its_map); its text."""
    with contextlib.chdir((scene[2] or FOG_BOX).parent):
        mitsuba_io.export(copy.deepcopy(scene[0]), xml, scene[1], approximate)
    return xml.read_text()


def deterministic(runs):
    """The pixels Mitsuba renders deterministically (its runs' spread within 1e-5 of their mean: the
    environment and a black plate seen directly; float32 leaves 1e-5 of noise), where z is undefined."""
    sums = runs.sum(-1)
    return sums.std(0) <= 1e-5 * sums.mean(0)


def agree(runs, ours, pixels=True):
    """Over `pixels`: those Mitsuba renders deterministically equal ours (image, variance) to 1e-3 relative (its
    float32 radiance of the constant is 1e-5 off; its repeated map blends texels within 1/128 of their edges),
    the rest within its noise and ours; the figures printed (docs/environment.md's table)."""
    image, variance = ours
    fixed = deterministic(runs)
    mean, img = runs.sum(-1).mean(0), image.sum(-1)
    off = np.abs(img - mean) / (np.abs(mean) + 1e-30)
    fixed, tested = fixed & pixels, ~fixed & pixels
    z = z_scores(runs, image, variance)[tested]
    figures = (f"z-tested {z.size}: mean z^2 {np.mean(z**2):.3g}, |z| > 4 {np.mean(np.abs(z) > 4):.1%}, largest "
               f"difference {off[tested].max():.2g}; deterministic {np.count_nonzero(fixed)} (worst "
               f"{off[fixed].max() if fixed.any() else 0.0:.2g})")
    print(figures)
    same = np.abs(img - mean) <= 1e-3 * np.abs(mean) + 1e-30
    assert np.all(same[fixed]) and within_noise(z, RUNS - 1), figures


def closer(runs, default, fine, pixels):
    """FINE directions' mean z^2 over `pixels` at least 4 times smaller than the default's (one render each, z
    without our variance)."""
    pixels = pixels & ~deterministic(runs)
    coarse, finer = (np.mean(z_scores(runs, img[0])[pixels] ** 2) for img in (default, fine))
    print(f"mean z^2 without our variance: {coarse:.3g} at COUNT, {finer:.3g} at FINE")
    assert finer < coarse / 4, (coarse, finer)


# ------------------------------------------------------------------- a constant environment, a grey plate

@pytest.fixture(scope="module")
def constant(mi, tmp_path_factory):  # noqa: F811 (the fixture)
    """(the exported XML, Mitsuba's runs of it, our quadrature (image, variance) at COUNT, at FINE, the pixels
    where COUNT gives FINE's image)."""
    scene = fog_box()
    xml = tmp_path_factory.mktemp("constant") / "fog_box.xml"
    text = export(scene, xml)
    default, fine = ours(scene), ours(scene, count=FINE)
    return text, mitsuba_runs(mi, xml), default, fine, converged(default[0], fine[0], None)


@pytest.mark.peers
def test_the_export_carries_the_constant_emitter_and_the_interior(constant):
    """The constant emitter with our radiance; the box an index-matched (null) shape holding the fog
    (sigma_t 0.8, albedo 0.75, isotropic) as its interior medium; no other medium (the sensor in vacuum)."""
    xml = constant[0]
    assert '<emitter type="constant">\n    <rgb name="radiance" value="0.2, 0.3, 0.5" />' in xml
    assert ('<bsdf type="null" />\n    <medium type="homogeneous" name="interior">\n'
            '      <rgb name="sigma_t" value="0.8, 0.8, 0.8" />') in xml
    assert 'name="albedo" value="0.7499999999999999' in xml and '<phase type="isotropic" />' in xml
    assert xml.count("<medium") == 1


@pytest.mark.peers
def test_pixels_the_lattice_resolves_agree_with_mitsuba(constant):
    """Where 64 directions give FINE's image to 1e-4 (the sky and the plate's top, 47 % of the pixels:
    every other one is in a shadow of the sky; each group of directions is exact there), quadrature is within
    Mitsuba's noise."""
    _, runs, default, _, ok = constant
    assert ok.mean() > 0.4, ok.mean()
    agree(runs, default, ok)


@pytest.mark.peers
def test_more_directions_bring_the_sky_shadows_to_mitsuba(constant):
    """Where 64 directions did not converge, FINE directions are closer to Mitsuba: the mean z^2 at
    least 4 times smaller (the difference is the lattice's)."""
    _, runs, default, fine, ok = constant
    closer(runs, default, fine, ~ok)


@pytest.mark.peers
@pytest.mark.xfail(strict=True, reason="Mitsuba's volpath (max_depth 2) adds light reflected by the grey plate to the "
                                       "pixels seen through the fog box (up to 3.4 %; a black plate removes it), "
                                       "which single scattering leaves out")
def test_every_pixel_agrees_with_mitsuba_at_fine_directions(constant):
    _, runs, _, fine, _ = constant
    agree(runs, fine)


@pytest.fixture(scope="module")
def black(mi, tmp_path_factory):  # noqa: F811 (the fixture)
    """(the scene with a black plate (reflectance 0), Mitsuba's runs of it)."""
    scene = fog_box(plate=0.0)
    xml = tmp_path_factory.mktemp("black") / "black.xml"
    export(scene, xml)
    return scene, mitsuba_runs(mi, xml)


@pytest.mark.peers
def test_with_a_black_plate_every_pixel_agrees_with_mitsuba(black):
    """With a black plate every pixel (the shadows of the sky too: each render a random sum of 64 hard
    shadows) of the mean of SEEDS renders at 64 directions is within Mitsuba's noise and our variance."""
    scene, runs = black
    agree(runs, ours(scene, seeds=SEEDS))


@pytest.mark.peers
def test_with_a_black_plate_every_pixel_agrees_with_mitsuba_at_fine_directions(black):
    """FINEST directions: every pixel of quadrature and of montecarlo (4 samples) within Mitsuba's noise and
    our variance."""
    scene, runs = black
    agree(runs, ours(scene, count=FINEST))
    agree(runs, ours(scene, "montecarlo", count=FINEST, samples=4, seed=5))


# ------------------------------------------------------------------- an equirectangular map, a black plate

def sky_map():
    """16 x 8 (float32-exact): above the horizon a sky from [0.25, 0.35, 0.55] + cos(theta) [0, 0.1, 0.35],
    one sun texel [12, 11, 9] (row 2, column 5), below it a dim ground [0.05, 0.04, 0.03]."""
    theta = (np.arange(8) + 0.5) / 8 * np.pi
    rows = np.where((theta < np.pi / 2)[:, None], [0.25, 0.35, 0.55] + np.cos(theta)[:, None] * [0.0, 0.1, 0.35],
                    [0.05, 0.04, 0.03])
    image = np.repeat(rows[:, None, :], 16, axis=1)
    image[2, 5] = [12.0, 11.0, 9.0]
    return image.astype(np.float32).astype(float)


@pytest.fixture(scope="module")
def sky(mi, tmp_path_factory):  # noqa: F811 (the fixture)
    """(the folder, the scene, the exported XML, Mitsuba's runs with the repeated map, our quadrature (image,
    variance) at COUNT and at FINE, the pixels Mitsuba renders deterministically (the map and the plate seen
    directly))."""
    folder = tmp_path_factory.mktemp("sky")
    write_exr(folder / "sky.exr", sky_map())
    write_exr(folder / "fine.exr", np.repeat(np.repeat(sky_map(), REPEAT, 0), REPEAT, 1))
    scene = fog_box(plate=0.0, light={"type": "environment", "map": "sky.exr"}, folder=folder)
    with pytest.warns(UserWarning, match='a map looked up "nearest"'):  # Mitsuba interpolates it: --approximate
        text = export(scene, folder / "scene.xml", approximate=True)
    (folder / "fine.xml").write_text(text.replace(str(folder / "sky.exr"), str(folder / "fine.exr")))
    runs = mitsuba_runs(mi, folder / "fine.xml")
    return folder, scene, text, runs, ours(scene), ours(scene, count=FINE), deterministic(runs)


@pytest.mark.peers
def test_the_export_carries_the_map(sky):
    """An envmap of the map's absolute path, turned by diag(-1, 1, -1) (Mitsuba's u = 0 is our centre column)."""
    folder, _, xml = sky[:3]
    assert f'<emitter type="envmap">\n    <string name="filename" value="{folder / "sky.exr"}" />' in xml
    assert 'value="-1.0 0.0 0.0 0.0 0.0 1.0 0.0 0.0 0.0 0.0 -1.0 0.0 0.0 0.0 0.0 1.0"' in xml


@pytest.mark.peers
def test_the_map_scene_agrees_with_mitsuba_at_fine_directions(sky):
    """FINE directions: the pixels Mitsuba renders deterministically (the map seen directly, the black
    plate) equal ours to 1e-3, and the rest are within its noise."""
    *_, runs, _, fine, fixed = sky
    assert 0.2 < fixed.mean() < 0.8, fixed.mean()
    agree(runs, fine)


@pytest.mark.peers
def test_the_map_scene_agrees_with_mitsuba(sky):
    """The mean of SEEDS renders at 64 directions: within Mitsuba's noise and its variance."""
    _, scene, _, runs = sky[:4]
    agree(runs, ours(scene, seeds=SEEDS))


@pytest.mark.peers
def test_more_directions_bring_the_map_scene_to_mitsuba(sky):
    """FINE directions' mean z^2 off the deterministic pixels at least 4 times smaller than 64's."""
    *_, runs, default, fine, _ = sky
    closer(runs, default, fine, True)


@pytest.mark.peers
@pytest.mark.xfail(strict=True, reason="Mitsuba's envmap interpolates the bitmap bilinearly, ours holds each texel "
                                       "constant: the 16 x 8 map seen directly differs by up to 420 % (the sun texel "
                                       "spreads to the rows beside it)")
def test_mitsuba_reads_our_map_as_we_do(mi, sky):  # noqa: F811 (the fixture)
    folder, *_, fine, fixed = sky
    coarse = mitsuba_runs(mi, folder / "scene.xml")[0].sum(-1)  # (the deterministic pixels need one run)
    np.testing.assert_allclose(coarse[fixed], fine[0].sum(-1)[fixed], rtol=1e-3, atol=1e-30)


@pytest.mark.peers
def test_an_export_from_another_folder_finds_its_map(sky, tmp_path):
    folder, scene = sky[:2]
    with contextlib.chdir(tmp_path), pytest.warns(UserWarning, match="--approximate"):
        mitsuba_io.export(copy.deepcopy(scene[0]), tmp_path / "elsewhere.xml", scene[1], True)
    assert f'name="filename" value="{folder / "sky.exr"}"' in (tmp_path / "elsewhere.xml").read_text()


# ------------------------------------------------------------------- the same map with filter = "mitsuba"

@pytest.fixture(scope="module")
def interpolated(mi, tmp_path_factory):  # noqa: F811 (the fixture)
    """(Mitsuba's runs of the 16 x 8 map itself, our quadrature (image, variance) at FINE with filter =
    "mitsuba", the pixels Mitsuba renders deterministically): the export is exact, no repeated copy of the map."""
    folder = tmp_path_factory.mktemp("interpolated")
    write_exr(folder / "sky.exr", sky_map())
    scene = fog_box(plate=0.0, light={"type": "environment", "map": "sky.exr", "filter": "mitsuba"}, folder=folder)
    export(scene, folder / "scene.xml")
    runs = mitsuba_runs(mi, folder / "scene.xml")
    return runs, ours(scene, count=FINE), deterministic(runs)


@pytest.mark.peers
def test_mitsuba_reads_a_mitsuba_filtered_map_as_we_do(interpolated):
    """With filter = "mitsuba" (bilinear, the first and last rows on the poles: envmap.cpp) the 16 x 8 map
    seen directly equals Mitsuba's to 1e-3 (the pixels it renders deterministically), where the nearest
    map is up to 420 % off (test_mitsuba_reads_our_map_as_we_do)."""
    runs, fine, fixed = interpolated
    assert 0.2 < fixed.mean() < 0.8, fixed.mean()
    np.testing.assert_allclose(runs[0].sum(-1)[fixed], fine[0].sum(-1)[fixed], rtol=1e-3, atol=1e-30)


@pytest.mark.peers
def test_the_mitsuba_filtered_map_scene_agrees_with_mitsuba_at_fine_directions(interpolated):
    """FINE directions sampled in proportion to the interpolated luminance: every pixel agrees."""
    runs, fine, _ = interpolated
    agree(runs, fine)
