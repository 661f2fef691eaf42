"""Mitsuba spectra sampled at wavelengths (`<spectrum value="400:0.3, 500:0.4, ...">`) read as Mitsuba 3's
RGB variants read them (raytrace/io/spectra.py), checked against Mitsuba itself.

MITSUBA holds the linear sRGB Mitsuba 3.9.1 (`scalar_rgb`) gives each spectrum: `mitsuba_rgb` below loads the
spectrum as an area emitter's radiance, a diffuse bsdf's reflectance or a homogeneous medium's albedo
(mi.load_string) and reads the value back with mi.traverse; test_stored_numbers_are_mitsubas (peers) checks
the table against Mitsuba as installed, so the table is how it was made. The cases: every spectrum of
mitsuba-data's Cornell box (cbox.xml), and edge cases: spectra narrower and wider than the CIE range
(360-830 nm), one outside it, narrow bands out of gamut (a reflectance clamped into [0, 1], emission and a
medium's coefficients to >= 0).

Tolerance: 4e-4 of each channel. Mitsuba's XYZ -> sRGB matrix (include/mitsuba/core/spectrum.h
`xyz_to_srgb`) is the Rec. 709 one for the white XYZ (0.950456, 1, 1.088754), ours (colour-science) the
IEC 61966-2-1 one for sRGB's own white (0.95047, 1, 1.08883): the two differ by the channel scales
(1 - 1.5e-4, 1 + 1.2e-5, 1 + 3.2e-4) (test_the_matrices_differ_by_channel_scales_only). Mitsuba's float32 sum
of 1000 terms adds about 1e-6. Leaving out D65 for a reflectance, or normalising D65 to exactly Y = 1
rather than Mitsuba's 1 / 98.9974 (1.1e-3), fails it.
"""
from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from raytrace import io
from raytrace.api import render
from raytrace.cli import main
from raytrace.errors import UserError
from raytrace.io import spectra

CBOX = Path(__file__).resolve().parent / "data" / "corpus" / "mitsuba-data" / "scenes" / "cbox"
CBOX_SPECTRA = dict(re.findall(r'id="(\w+)">\s*<spectrum name="reflectance" value="([^"]+)"',
                               (CBOX / "cbox.xml").read_text()))
CBOX_RADIANCE = "400:0, 500:8, 600:15.6, 700:18.4"
REL = 4e-4

# (kind, spectrum) -> Mitsuba 3.9.1 scalar_rgb's linear sRGB (mitsuba_rgb)
MITSUBA = {
    ("reflectance", CBOX_SPECTRA["white"]): [0.7350130081176758, 0.7356246113777161, 0.7362643480300903],
    ("reflectance", CBOX_SPECTRA["red"]): [0.49132004380226135, 0.04922810569405556, 0.05092189833521843],
    ("reflectance", CBOX_SPECTRA["green"]): [0.06828253716230392, 0.39776018261909485, 0.0862908735871315],
    ("reflectance", CBOX_SPECTRA["light"]): [0.7763667702674866, 0.7798100113868713, 0.776029109954834],
    ("emission", CBOX_RADIANCE): [20.71083641052246, 10.854634284973145, 2.7711520195007324],
    ("reflectance", "400:0, 500:0, 510:1, 520:0, 830:0"): [0.0, 0.09573166072368622, 0.006991606671363115],
    ("reflectance", "300:1, 900:1"): [0.9989852905273438, 0.9988737106323242, 0.998801589012146],
    ("reflectance", "850:1, 900:1"): [0.0, 0.0, 0.0],
    ("reflectance", "600:0, 610:3, 620:0"): [0.6195972561836243, 0.0, 0.0],
    ("emission", "500:0, 510:50, 520:0"): [0.0, 4.411212921142578, 0.31939804553985596],
    ("emission", "300:1, 900:1"): [1.2048836946487427, 0.9482281804084778, 0.9092668294906616],
    ("emission", "2.5"): [3.0119848251342773, 2.3707275390625, 2.2722902297973633],  # one number: flat, not grey
    ("medium", "400:0.5, 700:0.9"): [0.8193302750587463, 0.6904604434967041, 0.5518713593482971],
    ("medium", "500:2, 510:2"): [0.0, 0.1562216430902481, 0.02924635447561741],
    ("medium", "390:4, 420:7.5, 430:1.25, 431:9"): [0.11668845266103745, 0.0, 0.7583794593811035],
}
SENSOR = '<sensor type="perspective"><film type="hdrfilm"><integer name="width" value="8"/></film></sensor>'


def body(kind, value):
    """A scene body holding the spectrum as `kind` (the same XML for Mitsuba and for us)."""
    spectrum = f'<spectrum name="{ {"emission": "radiance"}.get(kind, kind)}" value="{value}"/>'
    if kind == "emission":
        return f'<shape type="sphere"><emitter type="area">{spectrum}</emitter></shape>'
    if kind == "reflectance":
        return f'<shape type="sphere"><bsdf type="diffuse">{spectrum}</bsdf></shape>'
    return (f'<sensor type="perspective"><medium type="homogeneous" name="exterior">'
            f'{spectrum.replace("medium", "albedo")}</medium></sensor>')


def ours(tmp_path, kind, value):
    """Our importer's reading of the spectrum (a medium's albedo: sigma_s over sigma_t = 1)."""
    path = tmp_path / "s.xml"
    path.write_text(f'<scene version="3.0.0">{"" if kind == "medium" else SENSOR}{body(kind, value)}</scene>')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raw = io.read_scene(path)
    if kind == "medium":
        return np.broadcast_to(raw["medium"]["sigma_s"], 3)
    if kind == "emission":
        return np.broadcast_to(raw["light"][0]["radiance"], 3)
    return np.broadcast_to(raw["shape"][0]["reflectance"], 3)


@pytest.mark.parametrize("kind,value", MITSUBA, ids=[f"{k}-{v[:24]}" for k, v in MITSUBA])
def test_reads_as_mitsuba_reads_it(tmp_path, kind, value):
    """Each spectrum through our importer agrees with Mitsuba's stored reading to REL per channel."""
    np.testing.assert_allclose(ours(tmp_path, kind, value), MITSUBA[kind, value], rtol=REL, atol=1e-7)


def test_the_matrices_differ_by_channel_scales_only():
    """Mitsuba's xyz_to_srgb (its six-decimal constants) is ours times diag(1 - 1.5e-4, 1, 1 + 3.2e-4) to
    float32: the bound REL rests on."""
    mitsubas = np.array([[3.240479, -1.537150, -0.498535], [-0.969256, 1.875991, 0.041556],
                         [0.055648, -0.204043, 1.057311]])
    scale = mitsubas @ np.linalg.inv(spectra._xyz_to_srgb())
    np.testing.assert_allclose(scale, np.diag(np.diag(scale)), atol=1e-6)
    assert np.all(np.abs(np.diag(scale) - 1.0) < 3.5e-4)


PAIR = 'write value="400:0.5, 500:0.6, ..."'
INCREASING = ("a sampled spectrum needs two or more wavelengths in increasing order", PAIR)


@pytest.mark.parametrize("value,problem,fix", [
    ("500:0.5, 400:0.6", *INCREASING), ("400:0.5, 400:0.6", *INCREASING), ("400:0.5", *INCREASING),
    ("400:0.5, 500", "'500' is not a wavelength:value pair", PAIR),
    ("400:0.5:1, 500:1", "'400:0.5:1' is not a wavelength:value pair", PAIR),
    ("400:x, 500:1", "'x' is not a number", "write a number"),
    ("400:nan, 500:1", "'nan' is not finite", "use a finite number"),
])
def test_malformed_spectra_refused_in_one_line(tmp_path, capsys, value, problem, fix):
    """One line naming the file, the line, the element and the fix; the command line exits 2."""
    path = tmp_path / "s.xml"
    path.write_text(f'<scene version="3.0.0">{SENSOR}\n{body("reflectance", value)}</scene>')
    with pytest.raises(UserError) as err:
        io.read_scene(path)
    msg = str(err.value)
    assert msg.startswith(f'{path}:2: <spectrum name="reflectance">: {problem}; {fix}') and "\n" not in msg
    assert main(["describe", str(path)]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [f"error: {msg}"]


def test_cornell_box_renders_as_its_rgb_twin_times_the_colour_ratios():
    """cbox.xml imports without a refusal and renders (quadrature, 16 x 16). Its twin cbox-rgb.xml has the
    same meshes, camera and light with colours of its own: the reflectances are the spectra taken without
    D65 (as an emitter's, near (0.886, 0.699, 0.666) for the white), the large and small boxes blue
    (0.45, 0.30, 0.90) instead of white, and radiance (18.387, 10.9873, 2.75357) against our (20.71, 10.85,
    2.77) of the spectrum. Surfaces here are lit directly by the one area light, so each pixel of the
    spectral render is the twin's times rho / rho_twin of its surface times L / L_twin (the light seen
    itself: L / L_twin): every lit pixel's ratio is one of those, to float32 rounding."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raws = [io.read_scene(CBOX / name) for name in ("cbox.xml", "cbox-rgb.xml")]
        images = [render(CBOX / name, "quadrature", width=16, height=16, spp=1).array[..., :3]
                  for name in ("cbox.xml", "cbox-rgb.xml")]
    (lamp, lamp_twin) = ([s for s in raw["shape"] if "emission" in s][0] for raw in raws)
    light = np.divide(lamp["emission"], lamp_twin["emission"])
    shapes = [sorted((np.round(s["vertices"], 9).tolist(), s["reflectance"]) for s in raw["shape"]) for raw in raws]
    assert [v for v, _ in shapes[0]] == [v for v, _ in shapes[1]]  # the same meshes, one to one
    ratios = np.array([light] + [np.divide(a, b) * light for (_, a), (_, b) in zip(*shapes)])
    spectral, twin = (image.reshape(-1, 3) for image in images)
    lit = np.all(twin > 0.0, axis=1)
    assert np.all(spectral[~lit] == 0.0) and np.count_nonzero(lit) > 100
    r = spectral[lit] / twin[lit]
    nearest = np.argmin(np.max(np.abs(r[:, None, :] / ratios[None] - 1.0), axis=2), axis=1)
    np.testing.assert_allclose(r, ratios[nearest], rtol=1e-5)
    assert len({tuple(ratios[i]) for i in nearest}) == 5  # the light, the white, red and green walls, the boxes


# ------------------------------------------------------------------------------------------- Mitsuba 3 itself

@pytest.fixture(scope="module")
def mi():
    mitsuba = pytest.importorskip("mitsuba")
    mitsuba.set_variant("scalar_rgb")
    return mitsuba


def mitsuba_rgb(mi, kind, value):
    """Mitsuba's linear sRGB of the spectrum in `body(kind, value)`, read back with mi.traverse."""
    params = mi.traverse(mi.load_string(f'<scene version="3.0.0">{body(kind, value)}</scene>'))
    end = {"emission": "radiance.value", "reflectance": "reflectance.value", "medium": "albedo.value.value"}[kind]
    (key,) = [k for k in params.keys() if k.endswith(end)]
    return [float(x) for x in params[key]]


@pytest.mark.peers
def test_stored_numbers_are_mitsubas(mi, tmp_path):
    """MITSUBA is what Mitsuba gives now (to float32), and ours agrees with it to REL."""
    for (kind, value), stored in MITSUBA.items():
        got = mitsuba_rgb(mi, kind, value)
        np.testing.assert_allclose(got, stored, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(ours(tmp_path, kind, value), got, rtol=REL, atol=1e-7)


@pytest.mark.peers
def test_cornell_box_colours_are_mitsubas(mi):
    """Every colour of cbox.xml as Mitsuba loads the file itself and as we import it."""
    params = mi.traverse(mi.load_file(str(CBOX / "cbox.xml")))
    theirs = {k: np.array(params[k], float) for k in params.keys() if k.endswith(("reflectance.value",
                                                                                  "radiance.value"))}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raw = io.read_scene(CBOX / "cbox.xml")
    (lamp,) = [s for s in raw["shape"] if "emission" in s]
    (radiance,) = [v for k, v in theirs.items() if k.endswith("radiance.value")]
    np.testing.assert_allclose(lamp["emission"], radiance, rtol=REL)
    reflectances = {tuple(s["reflectance"]) for s in raw["shape"]}
    mitsubas = [v for k, v in theirs.items() if k.endswith("reflectance.value")]
    assert len(reflectances) == len(mitsubas) == 4  # white (the boxes' is the same spectrum), red, green, light
    for rho in reflectances:
        assert min(np.max(np.abs(np.divide(rho, m) - 1.0)) for m in mitsubas) < REL
