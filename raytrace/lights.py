"""Lights: what the scene file describes (`Light`) and the arrays kernels read (`Lights`).

Only isotropic point lights exist today (SCENE_FORMAT.md): radiant intensity I per channel, so the
irradiance at distance d, before the medium's attenuation, is I / d^2 (the paper's eq. 5 and 4).
Each light has a type code so that spot and directional lights can join without new arrays.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

POINT = 0
NAMES = {POINT: "point"}


@dataclass
class Light:
    """One light of the scene file."""
    position: np.ndarray
    intensity: np.ndarray  # W/sr per channel
    kind: int = POINT


@dataclass(frozen=True)
class Lights:
    """All lights as float64 arrays: `kind` (L,), `position` (L, 3), `intensity` (L, 3)."""
    kind: np.ndarray
    position: np.ndarray
    intensity: np.ndarray

    @classmethod
    def of(cls, lights: list[Light]) -> "Lights":
        return cls(np.array([l.kind for l in lights], dtype=np.int64),
                   np.array([l.position for l in lights], dtype=float).reshape(-1, 3),
                   np.array([l.intensity for l in lights], dtype=float).reshape(-1, 3))

    def __len__(self) -> int:
        return len(self.kind)

    def irradiance(self, index: int, dist: np.ndarray) -> np.ndarray:
        """Unattenuated irradiance (N, 3) from light `index` at distances `dist` (N,) facing it."""
        return self.intensity[index][None, :] / (dist * dist)[:, None]
