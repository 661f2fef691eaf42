"""Preview images: scene-linear Rec.709 radiance to 8-bit sRGB through ACES 2.0's SDR output transform.

The view is OpenColorIO's built-in CG config (ACES 2.0, `VIEW` on the sRGB display): highlights roll
off and saturated colours are compressed into the display gamut instead of clipping channel by
channel, as a plain sRGB encode does. Exposure is in stops; by default (`auto_exposure`) the image's
log-average luminance is placed at middle grey, the usual key of a photographic exposure.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .errors import UserError

CONFIG = "cg-config-v4.0.0_aces-v2.0_ocio-v2.5"  # pinned, so previews do not change with OpenColorIO releases
SCENE_LINEAR = "Linear Rec.709 (sRGB)"
DISPLAY, VIEW = "sRGB - Display", "ACES 2.0 - SDR 100 nits (Rec.709)"
MIDDLE_GREY = 0.18
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec.709 / sRGB primaries
BAND_VALUES = 1 << 22  # floats per band: the temporaries of a 16k x 16k image stay near 100 MB


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


def to_display(image: np.ndarray, exposure: float | None = None) -> np.ndarray:
    """(H, W, 3) linear radiance -> (H, W, 3) uint8 sRGB: scaled by 2^exposure stops (automatic when
    None), then ACES 2.0's SDR view. Non-finite pixels show as black (nan) or white (+inf)."""
    image = np.asarray(image)
    stops = auto_exposure(image) if check_exposure(exposure) is None else exposure
    scale = 2.0 ** stops
    out = np.empty(image.shape, np.uint8)
    rows = max(1, BAND_VALUES // max(1, image[0].size)) if image.ndim == 3 and len(image) else 1
    cpu = _processor()
    for r in range(0, len(image), rows):
        band = np.nan_to_num(image[r:r + rows] * scale, nan=0.0, posinf=1e30, neginf=0.0)
        band = np.ascontiguousarray(np.clip(band, 0.0, 1e30), dtype=np.float32)
        cpu.applyRGB(band)
        out[r:r + rows] = np.clip(band, 0.0, 1.0) * 255.0 + 0.5
    return out
