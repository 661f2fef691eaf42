"""Preview images: scene-linear Rec.709 radiance to 8-bit sRGB through a display view.

Two views map a high dynamic range to the display (`to_display`); output/film.py adds the plain sRGB encode
("standard") and chooses among them:
- "neutral" (the default) is the Khronos PBR Neutral tone mapper (Khronos Group 2024,
  github.com/KhronosGroup/ToneMapping, PBR_Neutral/README.md, Apache-2.0): identity with a small toe
  below 0.76, then the largest channel is compressed towards 1 and the colour desaturated towards
  white only in proportion to the compression. Every step either scales RGB or moves it along the
  line to grey, so a lamp keeps its hue (in linear RGB exactly) and its saturation up to the shoulder.
- "aces" is OpenColorIO's built-in CG config (ACES 2.0, `VIEW` on the sRGB display): highlights roll off
  and saturated colours are compressed into the display gamut, which greys coloured lamps.
Exposure is in stops; by default (`auto_exposure`) the image's log-average luminance is placed at
middle grey, the usual key of a photographic exposure.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ..errors import UserError

CONFIG = "cg-config-v4.0.0_aces-v2.0_ocio-v2.5"  # pinned, so previews do not change with OpenColorIO releases
SCENE_LINEAR = "Linear Rec.709 (sRGB)"
DISPLAY, VIEW = "sRGB - Display", "ACES 2.0 - SDR 100 nits (Rec.709)"
DISPLAY_VIEWS = ("neutral", "aces")  # the views `to_display` forms; film.VIEWS adds "standard"
MIDDLE_GREY = 0.18
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec.709 / sRGB primaries
BAND_VALUES = 1 << 22  # floats per band: the temporaries of a 16k x 16k image stay near 100 MB
# PBR Neutral's constants (README's specification): F90 the Fresnel reflectance at normal incidence of
# IoR 1.5, the toe's width; K_S where highlight compression starts; K_D the speed of desaturation
F90, K_S, K_D = 0.04, 0.8 - 0.04, 0.15


@functools.cache
def _processor():
    import PyOpenColorIO as ocio

    config = ocio.Config.CreateFromBuiltinConfig(CONFIG)
    transform = ocio.DisplayViewTransform(src=SCENE_LINEAR, display=DISPLAY, view=VIEW)
    return config.getProcessor(transform).getDefaultCPUProcessor()


def auto_exposure(image: np.ndarray) -> float:
    """Stops that put the log-average luminance of the image's lit, finite pixels at middle grey
    (0 for an image with none)."""
    lum = np.asarray(image, dtype=np.float64).reshape(-1, 3) @ LUMINANCE
    lum = lum[np.isfinite(lum) & (lum > 0.0)]
    if not lum.size:
        return 0.0
    return math.log2(MIDDLE_GREY) - float(np.mean(np.log2(lum)))


def check_exposure(exposure, name: str = "exposure") -> float | None:
    """`exposure` as a finite float (stops), or None for automatic; UserError otherwise."""
    if exposure is None:
        return None
    try:
        value = float(exposure)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value) or isinstance(exposure, bool):
        raise UserError(f"{name}: {exposure!r} is not a finite number of stops; give e.g. 0.0, +1.5 or -2, "
                        "or leave it out for automatic exposure")
    return value


def pbr_neutral(rgb: np.ndarray) -> np.ndarray:
    """Khronos PBR Neutral of (..., 3) linear Rec.709, non-negative and finite -> linear Rec.709 in [0, 1]:
    f the toe offset, p the peak channel after it, p_n = 1 - (1 - K_S)^2 / (p + 1 - 2 K_S) the compressed
    peak, g = 1 / (K_D (p - p_n) + 1); out = c - f below K_S, else (c - f) (p_n / p) g + p_n (1 - g)."""
    x = rgb.min(axis=-1, keepdims=True)
    c = rgb - np.where(x <= 2.0 * F90, x - x * x / (4.0 * F90), F90)
    p = c.max(axis=-1, keepdims=True)
    top = np.maximum(p, K_S)  # the compressed branch, evaluated only where it is defined
    peak = 1.0 - (1.0 - K_S) ** 2 / (top + 1.0 - 2.0 * K_S)
    g = 1.0 / (K_D * (top - peak) + 1.0)
    return np.where(p <= K_S, c, c * (peak / top * g) + peak * (1.0 - g))


def srgb8(linear: np.ndarray) -> np.ndarray:
    """8-bit sRGB (IEC 61966-2-1 piecewise encode) of linear values, clipped to [0, 1] first."""
    x = np.clip(linear, 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return (srgb * 255.0 + 0.5).astype(np.uint8)


def to_display(image: np.ndarray, exposure: float | None = None, view: str = "neutral") -> np.ndarray:
    """(H, W, 3) linear radiance -> (H, W, 3) uint8 sRGB: scaled by 2^exposure stops (automatic when
    None), then `view` (DISPLAY_VIEWS): PBR Neutral or ACES 2.0's SDR view. Negative values count as 0;
    non-finite pixels show as black (nan) or white (+inf)."""
    image = np.asarray(image)
    stops = auto_exposure(image) if check_exposure(exposure) is None else exposure
    scale = 2.0 ** stops
    out = np.empty(image.shape, np.uint8)
    rows = max(1, BAND_VALUES // max(1, image[0].size)) if image.ndim == 3 and len(image) else 1
    for r in range(0, len(image), rows):  # in bands: the temporaries stay small
        band = np.clip(np.nan_to_num(image[r:r + rows] * scale, nan=0.0, posinf=1e30, neginf=0.0), 0.0, 1e30)
        if view == "neutral":
            out[r:r + rows] = srgb8(pbr_neutral(band.astype(np.float64)))
            continue
        band = np.ascontiguousarray(band, dtype=np.float32)
        _processor().applyRGB(band)
        out[r:r + rows] = np.clip(band, 0.0, 1.0) * 255.0 + 0.5
    return out
