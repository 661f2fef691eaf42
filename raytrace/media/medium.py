"""What every medium kind is: coefficients per channel, a phase function, and the interface the
renderer, the methods and the command line use instead of naming kinds (ARCHITECTURE.md).

A kind is a subclass of `Medium` in its own module (homogeneous.py, fog.py, atmosphere.py)
that declares its scene `type` name, its keys and their parsing (`parse`), its traits, `describe`,
`transmittance_on`, and, for the integrators, its numba hooks in the same module. media/__init__.py
holds the registry of kinds.

Parsing goes through a `read` object (scene/format.py's, bound to the file): read.fail(key,
problem, fix), read.unknown(table, keys, allowed), read.number(key, value, minimum=, positive=,
integer=), read.vec3(key, value), read.rgb(key, value), read.string(key, value, choices),
read.table(key, value), read.phase(value, key) -> (phase code, g), read.image(key, name, what) -> (an EXR
file's RGB, its path); each failure raises UserError.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np

from ..jit import exact_njit
from .phase import ISOTROPIC, NAMES as PHASE_NAMES


@dataclass
class Medium:
    sigma_a: np.ndarray  # per channel (kinds with a density: where it is 1)
    sigma_s: np.ndarray
    phase: int = ISOTROPIC  # a phase.py code
    g: float = 0.0  # Henyey-Greenstein asymmetry

    type_name: ClassVar[str] = ""  # medium.type in scene files
    keys: ClassVar[frozenset] = frozenset()  # the keys of its [medium] table
    homogeneous: ClassVar[bool] = False  # constant coefficients everywhere (the paper's model)
    has_ground: ClassVar[bool] = False  # an opaque ground of its own (`ground_hits`, `ground_surface`)
    particles: ClassVar[None] = None  # the particle layer (particles.py): only homogeneous media carry one

    @property
    def sigma_t(self) -> np.ndarray:
        return self.sigma_a + self.sigma_s

    @property
    def scatters(self) -> bool:
        return bool(np.any(self.sigma_s > 0.0))

    @classmethod
    def parse(cls, read, raw: dict) -> "Medium":
        """The medium of a [medium] table whose keys are already checked against `keys`."""
        raise NotImplementedError

    def check_scene(self, read, camera, lights):
        """Refuse a camera or lights this medium cannot hold (read.fail); nothing by default."""

    def transmittance_on(self, origins, dirs, a, b) -> np.ndarray:
        """Transmittance (N, 3) over [a, b] of the rays origins + t dirs (a, b arrays (N,) or scalars;
        b may be inf)."""
        raise NotImplementedError

    def density_at(self, point) -> float:
        """The density (the factor on sigma_a, sigma_s) at a point: 1 unless the kind has a profile."""
        return 1.0

    def phase_text(self) -> str:
        return PHASE_NAMES[self.phase] + (f" g={self.g}" if PHASE_NAMES[self.phase] == "hg" else "")

    def describe(self) -> list[str]:
        """The lines `render.py describe` prints for this medium."""
        return [f"medium: sigma_a {self.sigma_a.tolist()}, sigma_s {self.sigma_s.tolist()}, sigma_t "
                f"{self.sigma_t.tolist()}, phase {self.phase_text()}"]

    def fingerprint(self) -> str:
        """A digest of the kind and every field, for checkpoints (equal exactly when the media are)."""
        h = hashlib.sha256(self.type_name.encode())
        for f in fields(self):
            v = getattr(self, f.name)
            h.update(f.name.encode())
            if isinstance(v, np.ndarray):
                h.update(f"{v.dtype}{v.shape}".encode() + np.ascontiguousarray(v).tobytes())
            else:
                h.update(repr(v).encode())
        return h.hexdigest()


def kernel_arrays(n: int, origins, dirs, a, b) -> tuple:
    """`transmittance_on`'s arguments as the kernels take them: origins and dirs (n, 3), a and b (n,)
    (numbers broadcast), float64, C-contiguous and writable, so that one compiled signature serves every
    call (numba types a read-only array apart, and a broadcast array of one ray is contiguous but
    read-only: the warm-up's single rays would otherwise compile a signature no tile uses)."""
    return tuple(_kernel_array(v, shape) for v, shape in ((origins, (n, 3)), (dirs, (n, 3)), (a, (n,)), (b, (n,))))


def _kernel_array(v, shape):
    """v as `kernel_arrays` gives it: itself when it is one already, a number filled in (the same values
    as broadcasting, without NumPy's Python-level calls)."""
    if type(v) is np.ndarray and v.dtype == np.float64 and v.shape == shape and v.flags.c_contiguous \
            and v.flags.writeable:
        return v
    if isinstance(v, (int, float)):
        return np.full(shape, float(v))
    return np.require(np.broadcast_to(np.asarray(v, float), shape), float, ("C", "W"))


def exp_transmittance(kt: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """exp(-kt tau) per channel (N, 3) for unit optical depths tau (N,), exactly 1 in vacuum channels
    even for tau = inf, 0 where kt tau overflows (a GIL-free kernel, rounding as np.exp does)."""
    kt, tau = _kernel_array(kt, (len(kt),)), _kernel_array(tau, (len(tau),))
    out = np.empty((len(tau), len(kt)))
    _exp_transmittance(kt, tau, out)
    return out


@exact_njit
def _exp_transmittance(kt, tau, out):
    """`exp_transmittance` into out; a channel whose kt equals an earlier one's copies that channel's
    number (the same exp of the same product: a grey medium takes one exp per ray, not three)."""
    for i in range(tau.shape[0]):
        for c in range(kt.shape[0]):
            same = -1
            for e in range(c):
                if same < 0 and kt[e] == kt[c]:
                    same = e
            if same >= 0:
                out[i, c] = out[i, same]
            else:
                out[i, c] = 1.0 if kt[c] == 0.0 else math.exp(-kt[c] * tau[i])
