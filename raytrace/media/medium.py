"""What a medium is: its coefficients, its phase function, and the transmittance through it.

Today one homogeneous medium fills all space (the paper's model): extinction kt = sigma_a + sigma_s
per channel, so the transmittance over a length t is exp(-kt t).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .particles import Particles
from .phase import ISOTROPIC


@dataclass
class Medium:
    sigma_a: np.ndarray
    sigma_s: np.ndarray
    phase: int = ISOTROPIC  # a phase.py code
    g: float = 0.0  # Henyey-Greenstein asymmetry
    particles: Particles | None = None  # seed 003's particle layer (particles.py)

    @property
    def sigma_t(self) -> np.ndarray:
        return self.sigma_a + self.sigma_s

    @property
    def scatters(self) -> bool:
        return bool(np.any(self.sigma_s > 0.0))

    def transmittance(self, t: np.ndarray) -> np.ndarray:
        """exp(-kt t) per channel (N, 3) over lengths t (N,), exactly 1 in vacuum channels even for t = inf."""
        kt = self.sigma_t
        with np.errstate(invalid="ignore"):
            tr = np.exp(-kt[None, :] * np.asarray(t, float)[:, None])
        return np.where(kt[None, :] == 0.0, 1.0, tr)
