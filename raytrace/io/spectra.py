"""Spectra sampled at wavelengths read as Mitsuba 3's RGB variants read them (docs/formats/mitsuba.md).

Mitsuba (src/core/properties.cpp `get_texture`, src/core/spectrum.cpp `spectrum_list_to_srgb`) takes the
spectrum s as linear between its samples and zero outside them and forms the tristimulus values

    XYZ = k * sum_i s(w_i) D(w_i) (x(w_i), y(w_i), z(w_i)),   w_i = 360 + 470 i / 999 nm, i = 0 .. 999,

with the CIE 1931 2 degree colour matching functions x, y, z tabulated every 5 nm (linear between) and
k = 1 / sum_i y(w_i) (a unit spectrum has luminance Y = 1). D is 1 for an emitter; for anything else it is
the CIE D65 illuminant over D65_SCALE (Mitsuba's MI_CIE_D65_NORMALIZATION: a unit reflectance has
Y = 0.99889, not 1, under this sum). XYZ then goes to linear sRGB (Rec. 709 primaries, D65 white,
IEC 61966-2-1); Mitsuba clamps a reflectance into [0, 1] and anything else (emission, a medium's
coefficients) to >= 0. The CIE tables come from colour-science (CIE 015:2004: the observer, and D65 as
the D series at 6500 K * 1.4388 / 1.4380, which reproduces the CIE's D65 table).
"""
from __future__ import annotations

import functools

import numpy as np

CIE_NM = np.arange(360.0, 830.0 + 2.5, 5.0)  # the 95 wavelengths Mitsuba tabulates the CIE curves at
CIE_RANGE = (360.0, 830.0)  # nm
SUM_NM = np.linspace(*CIE_RANGE, 1000)  # the wavelengths the sum runs over
D65_SCALE = 98.99741751876255  # Mitsuba's D65 is divided by this (include/mitsuba/core/spectrum.h)


@functools.cache
def _weights() -> tuple[np.ndarray, np.ndarray]:
    """(emitter, other): the (3, 1000) weights k D(w_i) (x, y, z)(w_i) at SUM_NM for each kind."""
    import colour
    from colour.temperature import CCT_to_xy_CIE_D

    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"][CIE_NM]
    xyz = np.array([np.interp(SUM_NM, CIE_NM, c) for c in cmfs.T])
    d65 = colour.sd_CIE_illuminant_D_series(CCT_to_xy_CIE_D(6500.0 * 1.4388 / 1.4380))[CIE_NM]
    d = np.interp(SUM_NM, CIE_NM, d65)
    return xyz / np.sum(xyz[1]), xyz * d / (D65_SCALE * np.sum(xyz[1]))


@functools.cache
def _xyz_to_srgb() -> np.ndarray:
    """Linear sRGB from XYZ: the inverse of the matrix of sRGB's primaries and white point."""
    import colour

    srgb = colour.models.RGB_COLOURSPACE_sRGB
    return np.linalg.inv(colour.normalised_primary_matrix(srgb.primaries, srgb.whitepoint))


def to_srgb(wavelengths, values, emitter: bool, bounded: bool) -> np.ndarray:
    """The linear sRGB of the spectrum sampled at increasing `wavelengths` (nm), clamped as Mitsuba does."""
    s = np.interp(SUM_NM, wavelengths, values)
    s[(SUM_NM < wavelengths[0]) | (SUM_NM > wavelengths[-1])] = 0.0
    rgb = _xyz_to_srgb() @ (_weights()[0 if emitter else 1] @ s)
    return np.clip(rgb, 0.0, 1.0 if bounded else np.inf)
