"""Writes tests/data/lamp_in_glass_shadow_twins.json: a lamp in a glass cube (ior 1.5) in fog, a plate above the cube
casting a volumetric shadow, seen from above (tests/test_lamp_in_glass_shadows.py). Built from the geometry alone:
per point X on a pixel's camera ray and per face of the cube whose plane X lies beyond, Fermat's refraction point R
(tests/test_lamp_in_glass.py `exit_point`, 30-digit Newton on the optical path), the outside leg R -> X tested against
the plate's and the floor's triangles by a plain ray-triangle test (Moller-Trumbore, here), Fresnel's T and the ray
tube's irradiance (tests/test_lamp_in_glass.py `irradiance` of that face alone: central differences of the path map
in 30 digits). Along the ray the face's term switches where R crosses the face's edges and where the leg starts or
stops crossing a triangle: both found on 96 samples and bisected to 1e-14 of the part (`switches`); scipy quad_vec
integrates the isotropic fog's sigma_s / (4 pi) E exp(-sigma_t t) between all the breaks (epsrel 1e-11). A pixel adds
the floor's radiance (tests/test_lamp_in_glass.py `floor_radiance`; the plate does not shadow it: it lies above the
lamp and the floor below). Run: python -m tests.make_lamp_in_glass_shadow_twins (about 10 minutes)."""
import json
import math
from pathlib import Path
from unittest import mock

import numpy as np
from scipy import integrate

from . import oracle
from . import test_lamp_in_glass as glass
from .test_bounded_media import box_entry
from .test_lantern_fog import FOG, KS_OUT

OUT = Path(__file__).parent / "data" / "lamp_in_glass_shadow_twins.json"
PLATE = [[-0.6, 1.5, 0.9], [0.9, 1.5, 0.9], [0.9, 1.5, -0.6], [-0.6, 1.5, -0.6]]
CAMERA = {"position": [0.15, 6.0, 2.5], "look_at": [0.15, -1.6, -3.5], "fov": 50.0, "width": 8, "height": 6,
          "spp": 1}
PIXELS = [(2, 2), (3, 1), (4, 6), (5, 0)]  # (row, column): rays through the plate's shadow to the floor
FLOOR = [[-5.0, glass.FLOOR_Y, 5.0], [5.0, glass.FLOOR_Y, 5.0], [5.0, glass.FLOOR_Y, -5.0], [-5.0, glass.FLOOR_Y, -5.0]]
TRIANGLES = [np.array(q, float)[list(k)] for q in (PLATE, FLOOR) for k in ((0, 1, 2), (0, 2, 3))]


def scene():
    """The renderer's scene: tests/test_lamp_in_glass.py's lantern and floor in fog, the plate, this camera."""
    sc = glass.scene(glass.LAMP, FOG)
    sc["shape"].append({"primitive": "quad", "corners": PLATE, "reflectance": 0.5})
    sc["camera"] = CAMERA
    return sc


def crosses(tri, p, q):
    """Whether the segment pq crosses the triangle tri (Moller-Trumbore)."""
    e1, e2, d = tri[1] - tri[0], tri[2] - tri[0], q - p
    h = np.cross(d, e2)
    det = e1 @ h
    if det == 0.0:
        return False
    s = p - tri[0]
    u = (s @ h) / det
    k = np.cross(s, e1)
    v, t = (d @ k) / det, (e2 @ k) / det
    return 0.0 <= u <= 1.0 and v >= 0.0 and u + v <= 1.0 and 0.0 <= t <= 1.0


def exit_of(X, n):
    return np.array([float(v) for v in glass.exit_point(np.array(glass.LAMP["position"], float), X, n)])


def state(o, d, t, n):
    """(R on the face, the leg R -> X clear of every triangle) at X = o + t d for face n."""
    X = o + t * d
    R = exit_of(X, n)
    return glass.on_face(R, n), not any(crosses(tri, R, X) for tri in TRIANGLES)


def switches(o, d, lo, hi, n, samples=96):
    """The t in (lo, hi) where face n's `state` changes: on samples, each change bisected to 1e-14 of the part."""
    ts = lo + (hi - lo) * (np.arange(samples) + 0.5) / samples
    states = [state(o, d, t, n) for t in ts]
    out = []
    for a, b, sa, sb in zip(ts[:-1], ts[1:], states[:-1], states[1:]):
        if sa == sb:
            continue
        while b - a > 1e-14 * (hi - lo):
            mid = 0.5 * (a + b)
            a, b = (mid, b) if state(o, d, mid, n) == sa else (a, mid)
        out.append(0.5 * (a + b))
    return out


def face_irradiance(X, n):
    """`irradiance` (3,) of the lamp at X across the ray through face n alone."""
    with mock.patch.object(glass, "FACES", [n]):
        return glass.irradiance(glass.LAMP, X)


def pixel(j, i, epsrel=1e-11):
    """(the pixel's value (3,), its air-light (3,), the shadow breaks) of the twin."""
    o, d = oracle.camera_ray(CAMERA, i, j)
    assert box_entry(o, d, glass.LO, glass.HI)[1] is None
    end = (glass.FLOOR_Y - o[1]) / d[1]
    parts, cuts, shadow = [], {0.0, end}, []
    for n in glass.FACES:
        rate, depth = float(n @ d), float(n @ o) - 1.0
        lo, hi = (max(0.0, -depth / rate), end) if rate > 0.0 else (0.0, min(end, depth / -rate))
        if hi > lo:
            found = switches(o, d, lo, hi, n)
            parts.append((n, lo, hi))
            cuts |= {lo, hi, *found}
            shadow += [t for t in found if state(o, d, t * (1 - 1e-9), n)[1] != state(o, d, t * (1 + 1e-9), n)[1]]
    cuts = sorted(cuts)
    total = np.zeros(3)
    for a, b in zip(cuts, cuts[1:]):
        mid = 0.5 * (a + b)
        lit = [n for n, lo, hi in parts if lo <= mid <= hi and state(o, d, mid, n)[1]]
        if b > a and lit:
            total += integrate.quad_vec(lambda t: KS_OUT / (4.0 * math.pi) * math.exp(-glass.KA_OUT * t) * sum(
                face_irradiance(o + t * d, n) for n in lit), a, b, epsrel=epsrel, epsabs=1e-300, norm="max")[0]
    return total + glass.floor_radiance(glass.LAMP, o, d), total, sorted(shadow)


def main():
    rows = []
    for j, i in PIXELS:
        value, air, breaks = pixel(j, i)
        rows.append({"pixel": [j, i], "value": value.tolist(), "airlight": air.tolist(), "shadow_breaks": breaks})
        print(j, i, value, air, breaks, flush=True)
    OUT.write_text(json.dumps({"pixels": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
