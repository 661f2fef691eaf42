"""What every light kind is: the record it fills from the scene file (`Light`) and the interface
the rest of the package reads instead of naming kinds (ARCHITECTURE.md).

A kind is a module (point.py, spot.py, directional.py; the area lights quad.py, disk.py,
sphere.py; environment.py) that declares
- `NAME`, its scene `type`; `CODE`, its entry in `Light.kind`; `KEYS`, the keys of its table;
- `parse(read, key, raw) -> Light`, its [[light]] table whose keys are already checked against
  `KEYS`, through scene/format.py's `read` (media/medium.py lists its methods);
- `describe(light) -> str`, what `render.py describe` prints after "light[i]: ";
- `rows(light) -> Rows`, what it is to the kernels: rows of `Lights` (`one_row` for the kinds that
  are their own sample; an area light's emitter points, area.py, are spot rows);
- area kinds: `shape(light) -> (primitive, params)`, the emitter as a [[shape]] primitive (scene/format.py
  adds it: the camera sees it, it occludes);
- the environment (environment.py): `radiance(light, dirs)`, what rays leaving the scene see,
  `pdf(light, dirs)` and `directions(light, u)`, its importance sampling (its rows are directional
  rows);
and the kinds that are their own rows (point, spot, directional) also
- `irradiance(lights, index, to_points, dist)`, the unattenuated irradiance on surfaces facing it;
- `sample(position, axis, cone, li, px, py, pz)`, a numba hook: the light seen from the point p as
  (ux, uy, uz, dist, weight): the unit direction toward the light, its distance (inf: a distant
  sample, a direction only) and the weight of its emission toward p: the light's `intensity` row
  times `weight` is the radiant intensity (W/sr) toward p of a positional sample, whose irradiance
  on a surface facing it is that over dist^2, and the irradiance itself of a distant one. A point
  light is the kind with one deterministic sample, of weight 1.
lights/__init__.py holds the registry and `light_sample`, the kernels' one entry to the samples.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# the (cos_end, cos_start) of a light without a cone: F = 1 for every cosine >= -1 (spot.has_cone)
NO_CONE = (-3.0, -2.0)
MAX_POWER = 1e150  # a light's intensity or irradiance: its square (a Monte Carlo variance) must stay finite


@dataclass
class Light:
    """One light of the scene file: `kind` is its kind's CODE (0: point.py's); spot lights also have
    a unit `axis` and the cosines of their cone (`cos_end`, zero beyond) and of their
    full-intensity core (`cos_start`) and the falloff `curve` between (spot.CURVES; 0: smoothstep);
    directional lights a unit `axis` (direction of travel) and no position (zero)."""
    position: np.ndarray
    intensity: np.ndarray  # W/sr per channel (spot: on the axis; directional: irradiance W/m^2)
    kind: int = 0
    axis: np.ndarray | None = None
    cos_end: float = NO_CONE[0]
    cos_start: float = NO_CONE[1]
    curve: int = 0
    emitter: dict | None = None  # an area light's geometry (area.py); `intensity` is then its radiance
    two_sided: bool = False


@dataclass(frozen=True)
class Rows:
    """What one scene light is to the kernels: rows of `Lights` (position, intensity, row kind,
    axis, cone (cos_end, cos_start, curve)), (n, 3) arrays but `kind` (n,), and whether they are
    a cubature of an emitter (`cubature`: the light's value is approximated, error_bounds.py)."""
    position: np.ndarray
    intensity: np.ndarray
    kind: np.ndarray
    axis: np.ndarray
    cone: np.ndarray
    cubature: bool = False


def one_row(light: Light) -> Rows:
    """The one row of a light that is its own sample (point, spot, directional)."""
    axis = np.zeros(3) if light.axis is None else light.axis
    return Rows(np.reshape(light.position, (1, 3)), np.reshape(light.intensity, (1, 3)),
                np.array([light.kind], dtype=np.int64), np.reshape(axis, (1, 3)),
                np.array([[light.cos_end, light.cos_start, light.curve]], dtype=float))


def power(read, key, value):
    """`value`, a light's intensity or irradiance per channel, refused above MAX_POWER."""
    if np.any(value > MAX_POWER):
        read.fail(key, f"{value.max():g} exceeds {MAX_POWER:g} (the variance of an estimate, its square, would "
                  "overflow doubles)", "scale the scene's units of power down")
    return value
