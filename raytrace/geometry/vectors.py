"""Small vector helpers shared by the shapes, the lights and the shadows: a perpendicular unit
vector, the rotation of a transform."""
from __future__ import annotations

import math

import numpy as np


def perpendicular(v) -> np.ndarray:
    """A unit vector perpendicular to the unit vector `v`: v × x̂ (v × ŷ where v is near x̂),
    normalised; -perpendicular(v) is x̂ × v (ŷ × v), bit for bit."""
    alt = np.array([1.0, 0.0, 0.0]) if abs(v[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(v, alt)
    u /= np.linalg.norm(u)
    return u


def rotation_matrix(degrees):
    """Rz Ry Rx of the angles (x, y, z) in degrees: a shape's `rotate`, an environment's."""
    rx, ry, rz = np.radians(degrees)
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    mx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    my = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    mz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return mz @ my @ mx
