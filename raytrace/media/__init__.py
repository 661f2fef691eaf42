"""What a participating medium is: one module per kind (homogeneous.py, fog.py,
atmosphere.py) behind the interface of medium.py, phase functions (`phase.py`) and their series
(`legendre_moments.py`), the exponential integrals (`expint.py`) and Chapman's function
(`chapman.py`). How the air-light is computed lives in `raytrace.methods`.

`KINDS` maps the scene files' `medium.type` to the kind; `parse_medium` reads a [medium] table.
"""
from __future__ import annotations

from .atmosphere import Atmosphere
from .fog import HeightFog
from .homogeneous import Homogeneous
from .medium import Medium

KINDS = {kind.type_name: kind for kind in (Homogeneous, HeightFog, Atmosphere)}


def parse_medium(read, raw) -> Medium:
    """The medium of a scene file's [medium] table (None: the vacuum), through `read` (medium.py)."""
    if raw is None:
        return Homogeneous.vacuum()
    raw = read.table("medium", raw)
    kind = KINDS[read.string("medium.type", raw.get("type", Homogeneous.type_name), tuple(KINDS))]
    if not kind.homogeneous and "particles" in raw:
        read.fail("medium.particles", "the particle layer needs a homogeneous medium",
                  f'remove [medium.particles] or use type = "{Homogeneous.type_name}"')
    read.unknown("medium", raw, kind.keys)
    return kind.parse(read, raw)


__all__ = ["Atmosphere", "HeightFog", "Homogeneous", "KINDS", "Medium", "parse_medium"]
