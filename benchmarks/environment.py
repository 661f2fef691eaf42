"""The environment light: what it costs against a directional light of the same irradiance, and its error
against the number of directions (docs/environment.md).

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/environment.py [--quick]

Cost: 16 x 12 pixels of a height fog over a 6 x 6 ground quad, `quadrature`, volumetric shadows on, one
thread, lit by a constant environment L of N directions or by a directional light straight down of
irradiance pi L (what the sky gives the open ground). CPU seconds of each render after a warm-up (compilation
excluded), the lights interleaved, best of `rounds`.
Error: the twins of tests/test_environment.py (rays up through a height fog; a ground point under an opaque
plate) against `quadrature` with `environment.COUNT` set to N.
"""
import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import raytrace  # noqa: E402
from raytrace.camera import generate_rays  # noqa: E402
from raytrace.lights import environment  # noqa: E402
from tests import test_environment as twins  # noqa: E402

L = [0.2, 0.3, 0.5]
SKY = {"type": "environment", "radiance": L}
SUN = {"type": "directional", "direction": [0.0, -1.0, 0.0], "irradiance": [math.pi * v for v in L]}


def fog_scene(light):
    return raytrace.load({
        "camera": {"position": [0.0, 1.0, 5.0], "look_at": [0.0, 0.5, 0.0], "fov": 60.0, "width": 16, "height": 12},
        "shape": [{"primitive": "quad", "corners": [[-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0],
                                                     [-3.0, 0.0, -3.0]], "reflectance": 0.5}],
        "light": [light], "medium": twins.FOG})


def cpu_seconds(light, count):
    environment.COUNT = count
    start = time.process_time()
    raytrace.render(fog_scene(light), "quadrature", threads=1)
    return time.process_time() - start


def errors(counts):
    """The largest relative error over the fog twin's pixels and the plate twin's, per count."""
    fog = twins.scene([SKY], medium=twins.FOG, camera=twins.UP_CAMERA)
    origins, dirs = generate_rays(fog.camera)
    fog_ref = np.array([twins.fog_twin(o, d, L, L, 0.02, 0.1, 2.0) for o, d in zip(origins, dirs)])
    F = 4 * (2 / math.sqrt(2) * math.atan(1 / math.sqrt(2)) / (2 * math.pi))  # the plate's form factor
    plate = twins.scene([SKY], camera=twins.POINT_CAMERA, shapes=[twins.GROUND, twins.PLATE])
    for n in counts:
        environment.COUNT = n
        f = raytrace.render(fog, "quadrature", rtol=1e-10).array.reshape(-1, 3)
        p = raytrace.render(plate, "quadrature").array[0, 0]
        plate_error = np.abs(p / (0.5 * np.array(L) * (1 - F)) - 1).max()
        print(f"N = {n}: fog {np.abs(f / fog_ref - 1).max():.2g}, plate {plate_error:.2g}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    counts, rounds = ((16, 64), 1) if args.quick else ((16, 64, 256), 2)
    cpu_seconds(SUN, environment.COUNT), cpu_seconds(SKY, 4)  # compile
    best = {}
    for _ in range(rounds):
        for name, light, n in [("directional", SUN, environment.COUNT)] + [(f"environment N = {n}", SKY, n)
                                                                           for n in counts]:
            best[name] = min(best.get(name, math.inf), cpu_seconds(light, n))
    for name, s in best.items():
        print(f"{name}: {s:.2f} CPU s, {s / best['directional']:.1f} x directional")
    errors(counts + (1024,))


if __name__ == "__main__":
    main()
