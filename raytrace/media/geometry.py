"""Ray-light geometry shared by every air-light method (METHODS.md §1).

For a ray o + x w (|w| = 1, camera at x = 0) and a light p: x_h = (p - o)·w is the light's
projection coordinate, h = |(p - o) x w| its distance to the ray line (from the cross product, which
keeps full relative precision when the light is near the line), d_a = |p - o|. h is clamped to
H_MIN_REL * d_a so that a ray through a light gives a large but finite air-light.
"""
import math

from ..jit import njit

H_MIN_REL = 1e-9


@njit
def ray_light(ox, oy, oz, wx, wy, wz, px, py, pz):
    """(x_h, h, d_a) of the light (px, py, pz) relative to the ray."""
    rx, ry, rz = px - ox, py - oy, pz - oz
    xh = rx * wx + ry * wy + rz * wz
    cx = ry * wz - rz * wy
    cy = rz * wx - rx * wz
    cz = rx * wy - ry * wx
    h = math.sqrt(cx * cx + cy * cy + cz * cz)
    da = math.sqrt(rx * rx + ry * ry + rz * rz)
    h = max(h, H_MIN_REL * da, 1e-300)
    return xh, h, da
