"""Area lights: what a quad light costs against a point light of the same power, and how the cost grows
with the cubature's order (docs/area_lights.md).

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/area_lights.py [--quick]

The scene: a box room (reflecting walls) in an HG fog, lit by a 1 x 1 quad light facing down (radiance L,
power pi L A) or by a point light at its centre of the same power (intensity L A / 4, 4 pi I = pi L A).
Each render is timed after a warm-up render (compilation excluded), the two lights interleaved, median of
`rounds`; `analytic` at precision 1e-3 and 1e-6 and `quadrature` at rtol 1e-3 and 1e-6, volumetric shadows
on (the default). The quad's order is the pilot's (its seconds are in the render's); then at fixed orders
(the pilot's ladder narrowed to one order).
"""
import argparse
import math
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import raytrace  # noqa: E402
from raytrace.lights import cubature  # noqa: E402

L = 10.0


def room(light, w, h):
    return raytrace.load({
        "camera": {"position": [0.0, 0.0, 3.5], "look_at": [0.0, 0.0, -1.0], "fov": 80.0, "width": w, "height": h},
        "shape": [{"primitive": "box", "min": [-3.0, -2.0, -4.0], "max": [3.0, 2.0, 4.0],
                   "reflectance": [0.6, 0.5, 0.4]}],
        "light": [light],
        "medium": {"sigma_a": 0.05, "sigma_s": [0.2, 0.3, 0.5], "phase": {"type": "hg", "g": 0.5}}})


QUAD = {"type": "quad", "corners": [[-0.5, 1.9, -1.5], [0.5, 1.9, -1.5], [0.5, 1.9, -0.5], [-0.5, 1.9, -0.5]],
        "radiance": L}
POINT = {"position": [0.0, 1.9, -1.0], "intensity": L * 1.0 / 4.0}  # 4 pi I = pi L A, A = 1


def seconds(scene, method, params, rounds):
    """(median seconds, the cubature's rows: the pilot's choice)."""
    raytrace.render(scene, method, volumetric_shadows=True, **params)  # compile
    runs = [raytrace.render(scene, method, volumetric_shadows=True, **params) for _ in range(rounds)]
    return statistics.median(r.seconds for r in runs), runs[0].stats.get("cubature: rows")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    w, h, rounds = (48, 36, 1) if args.quick else (96, 72, 3)
    print(f"{w}x{h}, 1 spp, volumetric shadows on, median of {rounds}")
    cases = [("analytic", {"precision": 1e-3}), ("analytic", {"precision": 1e-6}), ("quadrature", {"rtol": 1e-3}),
             ("quadrature", {"rtol": 1e-6})]
    for method, params in cases:
        p = seconds(room(POINT, w, h), method, params, rounds)[0]
        q, rows = seconds(room(QUAD, w, h), method, params, rounds)
        print(f"{method} {params}: point {p:.3f} s, quad ({rows} rows) {q:.3f} s, ratio {q / p:.1f}", flush=True)
    ladder = cubature.AREA_LADDER
    for order in (2, 4, 8, 12, 16):
        cubature.AREA_LADDER = (order,)
        q = seconds(room(QUAD, w, h), "analytic", {"precision": 1e-3}, rounds)[0]
        print(f"analytic precision 1e-3, quad order {order} ({order * order} rows): {q:.3f} s")
    cubature.AREA_LADDER = ladder
    print(f"pi L A = {math.pi * L:.4f} W each")


if __name__ == "__main__":
    main()
