"""Small vector helpers shared by the shapes, the lights and the shadows."""
from __future__ import annotations

import numpy as np


def perpendicular(v) -> np.ndarray:
    """A unit vector perpendicular to the unit vector `v`: v × x̂ (v × ŷ where v is near x̂),
    normalised; -perpendicular(v) is x̂ × v (ŷ × v), bit for bit."""
    alt = np.array([1.0, 0.0, 0.0]) if abs(v[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(v, alt)
    u /= np.linalg.norm(u)
    return u
