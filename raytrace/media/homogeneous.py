"""`homogeneous` (the paper's model): extinction kt = sigma_a + sigma_s per channel everywhere, so
the transmittance over a length t is exp(-kt t); optionally the particle layer of "Rendering
Particles in a Shaft of Light" on top (`[medium.particles]`, particles.py). A file without [medium]
is the vacuum, a homogeneous medium of zero coefficients.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lights import NAMES, distant
from .medium import Medium, exp_transmittance
from .particles import Particles

PARTICLE_KEYS = {"density", "mu", "sigma", "cell", "offset", "step", "beta", "c1", "c2", "reflectance", "seed"}


@dataclass
class Homogeneous(Medium):
    particles: Particles | None = None  # the particle layer (particles.py)

    type_name = "homogeneous"
    keys = frozenset({"type", "sigma_a", "sigma_s", "phase", "particles"})
    homogeneous = True

    @classmethod
    def vacuum(cls) -> "Homogeneous":
        return cls(np.zeros(3), np.zeros(3))

    @classmethod
    def parse(cls, read, raw):
        sa = read.rgb("medium.sigma_a", raw.get("sigma_a", 0.0))
        ss = read.rgb("medium.sigma_s", raw.get("sigma_s", 0.0))
        particles = _particles(read, raw.get("particles"), bool(np.any(ss > 0.0)))
        return cls(sa, ss, *read.phase(raw.get("phase", "isotropic"), "medium.phase"), particles)

    def check_scene(self, read, camera, lights):
        """A directional or environment light cannot shine through a homogeneous medium filling all space."""
        if np.any(self.sigma_t > 0.0):
            for i, light in enumerate(lights):
                if distant(light):
                    name = NAMES[light.kind]
                    read.fail(f"light[{i}].type", f"{'an' if name[0] in 'aeiou' else 'a'} {name} light through a "
                              "homogeneous medium filling all "
                              "space arrives with zero transmittance", 'use medium.type = "height_fog", a vacuum '
                              "medium, or a point or spot light")

    def transmittance(self, t: np.ndarray) -> np.ndarray:
        """exp(-kt t) per channel (N, 3) over lengths t (N,), exactly 1 in vacuum channels even for
        t = inf."""
        return exp_transmittance(self.sigma_t, t)

    def transmittance_on(self, origins, dirs, a, b) -> np.ndarray:
        t = np.subtract(b, a, dtype=np.float64)
        return self.transmittance(t if t.ndim else np.full(len(origins), t))


def _particles(read, raw, scatters):
    """[medium.particles]: the particle layer (particles.py); defaults are the article's."""
    if raw is None:
        return None
    key = "medium.particles"
    raw = read.table(key, raw)
    read.unknown(key, raw, PARTICLE_KEYS)
    if not scatters:
        read.fail(key, "the particles scatter with the medium's sigma_s, which is zero",
                  "give the medium a sigma_s > 0 or remove [medium.particles]")
    if "beta" in raw and ("c1" in raw or "c2" in raw):
        read.fail(f"{key}.beta", "replaces the article's beta = ((1 - d) + c1) c2, so c1 and c2 would be ignored",
                  "give either beta or c1 and c2")
    d = Particles()
    density = float(read.number(f"{key}.density", raw.get("density", d.density), minimum=0.0))
    if density > 1.0:
        read.fail(f"{key}.density", f"scales the density term d in [0, 1] and must be at most 1, got {density!r}",
                  "use a value in [0, 1] (0: no particles)")
    refl = float(read.number(f"{key}.reflectance", raw.get("reflectance", d.reflectance), minimum=0.0))
    if refl > 1.0:
        read.fail(f"{key}.reflectance", f"exceeds 1 (particles would create energy), got {refl!r}",
                  "use a value in [0, 1]")
    seed = read.number(f"{key}.seed", raw.get("seed", d.seed), integer=True, minimum=0)
    if seed >= 2 ** 63:
        read.fail(f"{key}.seed", f"must be below 2^63, got {seed!r}", "use a smaller whole number")
    cell = float(read.number(f"{key}.cell", raw.get("cell", d.cell), positive=True))
    beta = raw.get("beta")
    return Particles(
        density=density,
        mu=float(read.number(f"{key}.mu", raw.get("mu", d.mu))),
        sigma=float(read.number(f"{key}.sigma", raw.get("sigma", d.sigma), positive=True)),
        cell=cell,
        offset=float(read.number(f"{key}.offset", raw.get("offset", d.offset), minimum=0.0)),
        step=float(read.number(f"{key}.step", raw.get("step", cell), positive=True)),
        beta=None if beta is None else float(read.number(f"{key}.beta", beta, positive=True)),
        c1=float(read.number(f"{key}.c1", raw.get("c1", d.c1), minimum=0.0)),
        c2=float(read.number(f"{key}.c2", raw.get("c2", d.c2), minimum=0.0)),
        reflectance=refl,
        seed=seed,
    )
