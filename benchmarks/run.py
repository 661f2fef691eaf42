"""One benchmark table: ratios measured in one process, with the machine and versions in its header.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/run.py [--quick] [--json out/benchmarks.json]

Every figure is a ratio of two measurements taken in the same run (timed renders take turns in
interleaved rounds; the median of each), so tables from different commits on the same machine can
be compared through the JSON file. Times are `Image.seconds` (render wall time on 2 threads,
compile excluded: every configuration is rendered once before timing). Rows:

- air-light cost: analytic render (precision 1e-6) / the same render without air-light, per phase
  function, on the box room of tests/conftest.py. "Without air-light" is the same scene with
  sigma_s = 0 and sigma_a = sigma_a + sigma_s (same sigma_t): the renderer skips the air-light
  when no channel scatters (`medium.scatters`).
- equal error: quadrature / analytic render time, per phase function, on the black-walled box room
  (tests/conftest.plate_room without its plate, so the image is the air-light). Analytic runs at
  precision 1e-6; quadrature at the loosest rtol of a ladder whose max relative error
  (`metrics.errors`) against quadrature at rtol 1e-12 is at most analytic's.
- equal time: ray-marching error / analytic error (mean relative, against quadrature at rtol
  1e-12) on the paper's scenes, ray marching's steps doubled until its render takes at least as
  long as analytic's (the two timed in turns at each step count). Skipped with a note when RAYTRACE_ASSETS does not find the meshes.
- spot / point: analytic render time (precision 1e-6) with the box room's light made a spot light
  (cone 60 degrees, full within 40, aimed down across the view) / with it a point light, per phase
  function.
- shadows: shadowed / unshadowed analytic render time (`volumetric_shadows=True`) on Sibenik, or on
  the plate room when the meshes are missing.
"""
import argparse
import json
import os
import platform
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import raytrace  # noqa: E402
from raytrace.metrics import errors  # noqa: E402
from raytrace.renderer import prepare  # noqa: E402
from tests.conftest import box_room, plate_room  # noqa: E402

PHASES = {"isotropic": "isotropic", "rayleigh": "rayleigh", "hg g=0.5": {"type": "hg", "g": 0.5},
          "hg g=0.9": {"type": "hg", "g": 0.9}, "hg g=-0.5": {"type": "hg", "g": -0.5}}
RTOLS = [10.0 ** -k for k in range(1, 12)]
PRECISION = 1e-6
THREADS = 2


def machine():
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor() or "unknown")

    def version(pkg):
        try:
            return metadata.version(pkg)
        except metadata.PackageNotFoundError:
            return "missing"

    def git(*args):
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True).stdout.strip()

    dirty = git("status", "--porcelain", "--", "raytrace")
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "numpy": version("numpy"),
            "numba": version("numba"), "embreex": version("embreex"),
            "commit": git("rev-parse", "--short", "HEAD") + ("+dirty raytrace/" if dirty else "")}


def render(prep, method="analytic", **kw):
    return raytrace.render(prepared=prep, method=method, threads=THREADS, **kw)


def medians(jobs, rounds):
    """Median render seconds of each (prep, method, kwargs) job over `rounds` interleaved rounds,
    after one untimed warm-up render of each; and each job's last image."""
    for prep, method, kw in jobs:
        render(prep, method, **kw)
    times = [[] for _ in jobs]
    images = [None] * len(jobs)
    for _ in range(rounds):
        for i, (prep, method, kw) in enumerate(jobs):
            images[i] = render(prep, method, **kw)
            times[i].append(images[i].seconds)
    return [float(np.median(t)) for t in times], images


def airlight_cost(size, rounds):
    rows = []
    for label, phase in PHASES.items():
        camera = {**box_room()["camera"], "width": size[0], "height": size[1]}
        air = box_room(camera=camera, medium={"sigma_a": 0.05, "sigma_s": 0.15, "phase": phase})
        none = box_room(camera=camera, medium={"sigma_a": 0.2, "sigma_s": 0.0, "phase": phase})
        (t_air, t_none), _ = medians([(prepare(raytrace.load(air)), "analytic", {"precision": PRECISION}),
                                      (prepare(raytrace.load(none)), "analytic", {"precision": PRECISION})], rounds)
        rows.append({"row": "analytic / no air-light (time)", "case": f"box room, {label}", "ratio": t_air / t_none,
                     "detail": f"{t_air:.3f} s / {t_none:.3f} s"})
    return rows


def equal_error(size, rounds):
    rows = []
    for label, phase in PHASES.items():
        prep = plate_room(phase, plate=False, width=size[0], height=size[1])
        ref = render(prep, "quadrature", rtol=1e-12).array
        e_a = errors(render(prep, precision=PRECISION).array, ref)["max_rel"]
        rtol, e_q = RTOLS[-1], None
        for r in RTOLS:
            e_q = errors(render(prep, "quadrature", rtol=r).array, ref)["max_rel"]
            if e_q <= e_a:
                rtol = r
                break
        (t_a, t_q), _ = medians([(prep, "analytic", {"precision": PRECISION}), (prep, "quadrature", {"rtol": rtol})],
                                rounds)
        reached = "" if e_q <= e_a else " (not reached: tightest rtol)"
        rows.append({"row": "quadrature / analytic at equal max error (time)", "case": f"air-light box, {label}",
                     "ratio": t_q / t_a,
                     "detail": f"analytic 1e-6: {t_a:.3f} s, err {e_a:.1e}; quadrature rtol {rtol:g}{reached}: "
                               f"{t_q:.3f} s, err {e_q:.1e}"})
    return rows


def paper_scenes(size):
    out, notes = {}, []
    for name in ("sibenik", "bridge", "conference"):
        try:
            out[name] = prepare(raytrace.load(name, overrides=[f"camera.width={size[0]}", f"camera.height={size[1]}",
                                                               "camera.spp=1"]))
        except raytrace.UserError as exc:
            notes.append(f"{name} skipped: {str(exc).splitlines()[0]}")
    return out, notes


def equal_time(scenes, rounds):
    rows = []
    for name, prep in scenes.items():
        ref = render(prep, "quadrature", rtol=1e-12).array
        steps = 1
        while True:  # each step count timed in turns with analytic
            (t_a, t_m), (img_a, img_m) = medians([(prep, "analytic", {"precision": PRECISION}),
                                                  (prep, "raymarch", {"steps": steps})], rounds)
            if t_m >= t_a or steps >= 2 ** 14:
                break
            steps *= 2
        e_a, e_m = errors(img_a.array, ref)["mean_rel"], errors(img_m.array, ref)["mean_rel"]
        rows.append({"row": "ray marching / analytic at equal time (mean rel. error)", "case": name,
                     "ratio": e_m / max(e_a, 1e-300),
                     "detail": f"analytic 1e-6: {t_a:.3f} s, err {e_a:.1e}; raymarch {steps} steps: {t_m:.3f} s, "
                               f"err {e_m:.1e}"})
    return rows


def spot_vs_point(size, rounds):
    rows = []
    for label, phase in PHASES.items():
        camera = {**box_room()["camera"], "width": size[0], "height": size[1]}
        medium = {"sigma_a": 0.05, "sigma_s": 0.15, "phase": phase}
        point = box_room(camera=camera, medium=medium)
        light = {**point["light"][0], "type": "spot", "look_at": [0.0, -2.0, -2.0], "cone_angle": 60.0,
                 "falloff_start": 40.0}
        spot = box_room(camera=camera, medium=medium, light=[light])
        (t_spot, t_point), images = medians([(prepare(raytrace.load(spot)), "analytic", {"precision": PRECISION}),
                                             (prepare(raytrace.load(point)), "analytic", {"precision": PRECISION})],
                                            rounds)
        st = images[0].stats
        rows.append({"row": "spot / point analytic (time)", "case": f"box room, {label}", "ratio": t_spot / t_point,
                     "detail": f"{t_spot:.3f} s / {t_point:.3f} s; {st['spot_band_pieces']} band pieces, "
                               f"{st['spot_pieces_by_quadrature']} pieces by quadrature, "
                               f"fallback {100 * st['fallback_fraction']:.2f}%"})
    return rows


def shadows(prep, case, rounds):
    (t0, t1), _ = medians([(prep, "analytic", {"precision": PRECISION}),
                           (prep, "analytic", {"precision": PRECISION, "volumetric_shadows": True})], rounds)
    return [{"row": "shadowed / unshadowed analytic (time)", "case": case, "ratio": t1 / t0,
             "detail": f"{t1:.3f} s / {t0:.3f} s"}]


def table(info, rows, notes, seconds, quick):
    head = (f"**raytrace benchmarks** ({'quick' if quick else 'full'}, {seconds:.0f} s): commit {info['commit']}; "
            f"{info['cpu']}, {info['cores']} cores; Python {info['python']}, numpy {info['numpy']}, "
            f"numba {info['numba']}, embreex {info['embreex']}; {THREADS} threads, medians of interleaved rounds")
    lines = [head, "", "| ratio | case | value | measured |", "|---|---|---|---|"]
    lines += [f"| {r['row']} | {r['case']} | {r['ratio']:.3g}x | {r['detail']} |" for r in rows]
    lines += [f"\n({n})" for n in notes]
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small images, fewer rounds (under 3 minutes)")
    ap.add_argument("--json", default=str(ROOT / "out" / "benchmarks.json"), help="where to write the rows as JSON")
    args = ap.parse_args()
    start = time.perf_counter()
    box, paper, sibenik, rounds = ((240, 180), (384, 192), (512, 256), 7) if args.quick else \
        ((320, 240), (512, 256), (1024, 512), 9)
    rows = airlight_cost(box, rounds) + equal_error(box, rounds) + spot_vs_point(box, rounds)
    scenes, notes = paper_scenes(paper)
    rows += equal_time(scenes, rounds)
    if "sibenik" in scenes:
        big = prepare(raytrace.load("sibenik", overrides=[f"camera.width={sibenik[0]}",
                                                          f"camera.height={sibenik[1]}", "camera.spp=1"]))
        rows += shadows(big, f"sibenik {sibenik[0]}x{sibenik[1]}", max(3, rounds // 2))
    else:
        notes.append("paper scenes missing: shadow row on the plate room instead (set RAYTRACE_ASSETS)")
        rows += shadows(plate_room({"type": "hg", "g": 0.5}, width=box[0], height=box[1]), "plate room", rounds)
    info = machine()
    seconds = time.perf_counter() - start
    print(table(info, rows, notes, seconds, args.quick))
    path = Path(args.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"machine": info, "quick": args.quick, "seconds": seconds, "rows": rows,
                                "notes": notes}, indent=2) + "\n")
    print(f"\n(written to {path})")


if __name__ == "__main__":
    main()
