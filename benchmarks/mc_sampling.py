"""Variance and cost of the Monte Carlo distance-sampling modes (equiangular, mis, cdf).

    python benchmarks/mc_sampling.py [--width 32 --height 24 --samples 16 --threads 1]

Scenes (tests/conftest.py box_room, one light, walls black so that the image is the air-light):
  (a) unoccluded, isotropic and HG g = 0.9;
  (b) a plate just below the light, volumetric_shadows = True, shadow_test = samples (a shadow ray
      per sample point); cdf with shadow_test = intervals (the lit intervals) is listed too.
Per mode: the mean over pixel-channels of the per-pixel relative variance var / ref^2 that the render
reports (`Image.variance`; ref: quadrature at rtol 1e-12, same camera rays, pixels with ref below
1e-3 of the maximum left out), the measured mean squared relative error against ref (a check on the
reported variance), the render's CPU time (best of 3) per sample (per camera ray and
iteration; an iteration of mis draws one distance of each strategy), and the efficiency
var x time (relative variance x CPU seconds: independent of the sample count, lower is better).
Unoccluded, cdf draws no distance (every sample's weight f/p is F(ell) wherever it lands), so its
time is that of one closed-form evaluation per segment whatever `samples` is.
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import raytrace  # noqa: E402
from raytrace.camera import generate_rays  # noqa: E402
from raytrace.methods import montecarlo as mc  # noqa: E402
from raytrace.methods.geometry import segment_geometry  # noqa: E402
from raytrace.segments import whole_rays  # noqa: E402
from tests.conftest import plate_room  # noqa: E402

PHASES = {"isotropic": "isotropic", "hg 0.9": {"type": "hg", "g": 0.9}}


def run(prep, threads, **kw):
    """The render and its CPU seconds (process time, best of 3: robust to other jobs on the machine;
    with threads = 1 it is the render's own time plus a one-ray warm-up)."""
    best = None
    for _ in range(3):
        t0 = time.process_time()
        img = raytrace.render(prepared=prep, threads=threads, seed=1, **kw)
        sec = time.process_time() - t0
        if best is None or sec < best[1]:
            best = (img, sec)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=32)
    ap.add_argument("--height", type=int, default=24)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    n_rays = args.width * args.height
    print(f"box room {args.width}x{args.height}, 1 spp, samples = {args.samples}, threads = {args.threads}\n")
    print("| scene | phase | sampling | shadow test | rel. variance | measured MSE (rel.) | us / sample | "
          "var x time | efficiency vs equiangular |")
    print("|---|---|---|---|---|---|---|---|---|")
    for occluded in (False, True):
        for pname, phase in PHASES.items():
            prep = plate_room(phase, occluded, args.width, args.height)
            ref = raytrace.render(prepared=prep, method="quadrature", rtol=1e-12, volumetric_shadows=occluded,
                                  threads=args.threads).array
            lit = ref > 1e-3 * ref.max()
            rows = [("equiangular", "samples"), ("mis", "samples"), ("cdf", "samples")] if occluded else \
                [("equiangular", None), ("mis", None), ("cdf", None)]
            if occluded:
                rows.append(("cdf", "intervals"))
            base = None
            for mode, test in rows:
                kw = {"method": "montecarlo", "sampling": mode, "samples": args.samples}
                if occluded:
                    kw.update(volumetric_shadows=True, shadow_test=test)
                img, seconds = run(prep, args.threads, **kw)
                relvar = float(np.mean(img.variance[lit] / ref[lit] ** 2))
                mse = float(np.mean(((img.array[lit] - ref[lit]) / ref[lit]) ** 2))
                us = 1e6 * seconds / (n_rays * args.samples)
                eff = relvar * seconds
                if base is None:
                    base = eff
                gain = "inf" if eff == 0.0 else f"{base / eff:.3g}x"
                print(f"| {'(b) plate, shadows' if occluded else '(a) unoccluded'} | {pname} | {mode} | "
                      f"{test or '-'} | {relvar:.3e} | {mse:.3e} | {us:.3g} | {eff:.3e} | {gain} |")
                extra = ", ".join(f"{k.removeprefix('cdf: ')} {v:.3g}" for k, v in img.stats.items()
                                  if k.startswith("cdf:"))
                if extra:  # the lit-interval and unoccluded paths report them (shadow rays per sample do not)
                    print(f"|  |  |  | ({extra}) |  |  |  |  |  |")
            sys.stdout.flush()
    # the inversion alone: draws per second and Newton/bisection steps, on the unoccluded scenes' segments
    print("\ninversion alone (montecarlo.sample_points_cdf on the unoccluded scenes' camera segments):\n")
    print("| phase | us / draw | Newton steps / draw | bisection steps / draw | closed forms / draw | "
          "quadrature fallback share |")
    print("|---|---|---|---|---|---|")
    for pname, phase in PHASES.items():
        prep = plate_room(phase, False, args.width, args.height)
        cam = prep.scene.camera
        o, d = generate_rays(cam, slice(0, cam.height), slice(0, cam.width))
        t, _ = prep.accel.first_hit(o, d)
        segs = whole_rays(o, d, t, np.arange(len(o), dtype=np.uint64), 1, 1, prep.accel.scale)
        med, lights = prep.scene.medium, prep.lights
        xh, h, da, cone = segment_geometry(segs, lights)
        n = args.samples
        pos = np.zeros((len(segs), n, 1, 3, 3))
        w = np.zeros((len(segs), n, 1, 3))
        st = np.zeros(mc.CDF_STATS)
        prec, coeffs = mc.cdf_setup(med)
        call = lambda: mc.sample_points_cdf(segs.origins, segs.dirs, xh, h, da, segs.length, cone, segs.keys,  # noqa: E731
                                            segs.stream, np.uint64(1), lights.intensity[segs.light], med.sigma_t,
                                            med.sigma_s, med.phase, med.g, n, prec, coeffs, pos, w, st)
        call()
        st[:] = 0.0
        t0 = time.process_time()
        call()
        sec = time.process_time() - t0
        inv = st[mc.CS_INVERSIONS]
        print(f"| {pname} | {1e6 * sec / inv:.3g} | {st[mc.CS_NEWTON] / inv:.2f} | {st[mc.CS_BISECT] / inv:.2f} | "
              f"{st[mc.CS_EVALS] / inv:.2f} | {st[mc.CS_FALLBACK] / st[mc.CS_EVALS]:.2f} |")


if __name__ == "__main__":
    main()
