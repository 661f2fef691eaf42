"""Compile time of the first render of every bundled scene, with an empty kernel cache.

    RAYTRACE_ASSETS=../shared/scenes python benchmarks/compile_time.py [--profile] [--scenes a,b] [--tree DIR]
                                                                       [--before DIR] [--runs N] [--cached W]
                                                                       [--phases] [--ahead]

One subprocess per scene (and one for the built-in default scene), each with `RAYTRACE_CACHE`
pointed at a fresh empty folder, renders the scene through the command line at `--width` pixels
(one thread) with its own method, spp and shadows. numba announces every compilation as a
`numba:compile` event (numba.core.event); a listener takes the compiling thread's CPU time
(`time.thread_time`) at each start and end, so the figures are CPU seconds of compiling, which a
busy machine inflates far less than wall time. Per scene: the compile CPU seconds (the outermost
compilations summed), the number of compiled specialisations, those compiled after the warm-up
(`renderer.prepare_task`: a compile during the tiles is late, it happens after the compile notice),
the wall seconds of the warm-up and the process's whole CPU time (in --json: its CPU seconds when it started
the compile worker and when the warm-up reached the worker's gate, and the wall seconds it waited there); from outside the process, the wall
seconds to the first image (the command's whole run: start, imports, compile, render, writing) and
the CPU seconds of the process and of its children (the compile worker of
rendering/compile_ahead.py, whose compilations the listener does not see). The target: compile within 10 s
per scene on the 2-core machine of docs/benchmarks.md.

--profile adds, per scene, the dispatchers with the largest inclusive compile time (a dispatcher's
compilation includes those of the functions it calls that were not compiled yet; a recursive one is
counted once) and those with the largest exclusive time (without those nested compilations: typing
and lowering its own code, and optimising and emitting its module, which holds a copy of every
function it calls, so a deep chain of calls over one integrand pays for the integrand at each level).
--phases splits the compile CPU seconds, over all dispatchers, into numba's front end (type inference;
lowering to LLVM IR; its other passes: bytecode, SSA, rewrites, inlining; dispatch) and LLVM's part
(the IR printed and parsed, function passes, module passes over the module with its callees linked
in, machine code), each without the phases nested in it (a callee compiled during its caller's type
inference counts in its own phases); with --profile, each exclusive figure split into numba's part
and LLVM's (with --before or --runs, in --json's figures of each run). --tree runs the scenes against another checkout's `raytrace` (its root on PYTHONPATH),
e.g. an older commit's `git archive`, for before/after tables; --before DIR measures that checkout
too, alternating with --tree's, scene by scene (paired runs: both see the same load), and --runs N
repeats each measurement N times, giving every run's compile CPU seconds, wall seconds to the first
image and total CPU seconds, and their medians. --cached W
then renders each scene again at W pixels wide in a second process on the same cache (its kernels all
loaded from it): the CPU seconds of that render's `main` (warm render speed, to compare two checkouts
like with like) and what it compiled (nothing, when the cache works). --ahead measures, instead of the
render's process, the group of kernels its compile worker would compile (rendering/compile_ahead.py's call,
made in the measured process on its empty cache, which then stops): its compile CPU seconds, its compilations
and with --profile its dispatchers (the process's CPU seconds include the scene's loading, not a worker's
imports). Scenes whose meshes come from
`render.py assets` (sibenik, conference) run only when RAYTRACE_ASSETS is set.
"""
import argparse
import json
import resource
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = "(default)"  # the built-in default scene: render.py without a scene
ASSET_SCENES = ("sibenik", "conference")  # scene.catalogue.ARCHIVES' scenes


def scene_names(assets: bool) -> list[str]:
    names = sorted(p.stem for p in (ROOT / "scenes").glob("*.toml"))
    return [DEFAULT] + [n for n in names if assets or n not in ASSET_SCENES]


class Phases:
    """Thread-CPU seconds per compile phase, each without the phases nested in it, by wrapping numba's
    pass and code-library methods (this process only: a measurement, not a change to the kernels)."""
    WRAPPED = (("core.codegen", "CPUCodeLibrary", "add_ir_module", "LLVM: IR printed and parsed"),
               ("core.codegen", "CPUCodeLibrary", "_optimize_functions", "LLVM: function passes"),
               ("core.codegen", "CPUCodeLibrary", "_optimize_final_module", "LLVM: module passes"),
               ("core.codegen", "JITCodeLibrary", "_finalize_specific", "LLVM: machine code"),
               ("core.typed_passes", "BaseTypeInference", "run_pass", "numba: type inference"),
               ("core.typed_passes", "NativeLowering", "run_pass", "numba: lowering"),
               ("core.compiler_machinery", "PassManager", "run", "numba: other passes"),
               ("core.dispatcher", "_DispatcherBase", "_compile_for_args", "numba: dispatch"))

    def __init__(self, owner=lambda: ""):
        import importlib

        self.seconds, self.stack, self.owner, self.by_owner = {}, [], owner, {}
        for module, cls, attr, phase in self.WRAPPED:
            owner = getattr(importlib.import_module(f"numba.{module}"), cls)
            setattr(owner, attr, self._wrap(getattr(owner, attr), phase))

    def _wrap(self, fn, phase):
        def timed(*args, **kwargs):
            start = time.thread_time()
            self.stack.append(0.0)
            try:
                return fn(*args, **kwargs)
            finally:
                spent = time.thread_time() - start
                nested = self.stack.pop()
                self.seconds[phase] = self.seconds.get(phase, 0.0) + spent - nested
                side = self.by_owner.setdefault(self.owner(), {})
                side[phase[:4]] = side.get(phase[:4], 0.0) + spent - nested
                if self.stack:
                    self.stack[-1] += spent
        return timed


class Compiles:
    """A numba:compile listener: per event its dispatcher's name, thread-CPU start and end, depth."""

    def __init__(self):
        self.events, self.stack, self.phase = [], [], "before"

    def on(self, event):
        from numba.core import event as ev

        now = time.thread_time()
        if event.status == ev.EventStatus.START:
            d = event.data["dispatcher"]
            name = f"{d.py_func.__module__}.{d.py_func.__qualname__}"
            self.stack.append(len(self.events))
            self.events.append({"name": name, "args": str(event.data["args"]), "start": now, "end": None, "depth": len(self.stack) - 1,
                                "phase": self.phase, "outer": [self.events[i]["name"] for i in self.stack[:-1]]})
        else:
            self.events[self.stack.pop()]["end"] = now


class _Ahead(BaseException):
    """The end of an --ahead measurement: the worker's group compiled (not an error: no handler catches it)."""


def worker(scene: str, width: int, out: Path, phases: bool = False, ahead: bool = False) -> dict:
    """Render `scene` in this process (an empty cache set by the caller) and return the figures; `ahead`: compile
    the compile worker's group here instead, then stop."""
    from numba.core import event as ev

    rec = Compiles()
    split = Phases(lambda: rec.events[rec.stack[-1]]["name"] if rec.stack else "") if phases else None

    try:
        from raytrace.rendering import renderer
    except ImportError:  # a tree from before the packages (--tree)
        from raytrace import renderer
    from raytrace.cli import main


    class Listener(ev.Listener):
        def on_start(self, event):
            rec.on(event)

        def on_end(self, event):
            rec.on(event)

    prepare_task = renderer.prepare_task
    warm = {}

    def timed(prep, task):
        rec.phase = "warm-up"
        start = time.perf_counter()
        try:
            return prepare_task(prep, task)
        finally:
            warm["wall"] = time.perf_counter() - start
            rec.phase = "late"

    renderer.prepare_task = timed
    gate = {}
    try:
        from raytrace.rendering import compile_ahead
    except ImportError:  # a tree without it
        compile_ahead = None
    if compile_ahead is not None:
        wait = compile_ahead.Ahead.wait

        def waited(self, stop=False):
            gate.setdefault("cpu", time.process_time())  # this process's CPU seconds when it reached the gate
            start = time.perf_counter()
            try:
                return wait(self, stop)
            finally:
                gate["wall"] = gate.get("wall", 0.0) + time.perf_counter() - start

        compile_ahead.Ahead.wait = waited
        begin = compile_ahead.Ahead.__init__

        def begun(self, *a):
            gate.setdefault("start_cpu", time.process_time())  # this process's CPU seconds when the worker started
            return begin(self, *a)

        compile_ahead.Ahead.__init__ = begun
        if ahead:
            def start(split, fn, *args, later=False):
                rec.phase = "worker"
                rec.events.clear()  # (what this process compiled before: not the worker's)
                if split:  # (else the worker is not started: its group is empty)
                    fn(*args)
                raise _Ahead
            compile_ahead.start = start
    args = ([] if scene == DEFAULT else [scene]) + ["--width", str(width), "--threads", "1", "--quiet",
                                                   "--out", str(out / "image.exr")]
    with ev.install_listener("numba:compile", Listener()):
        main_cpu = time.process_time()
        try:
            status = main(args)
        except _Ahead:
            status = 0
        main_cpu = time.process_time() - main_cpu
    if status != 0:
        raise SystemExit(f"{scene}: render.py exited with {status}")
    top = [e for e in rec.events if e["depth"] == 0]
    inclusive = {}
    for e in rec.events:
        if e["name"] not in e["outer"]:  # a recursive compile is inside its own outer one
            inclusive[e["name"]] = inclusive.get(e["name"], 0.0) + e["end"] - e["start"]
    exclusive = {}  # without the compilations nested in it: what compiling the dispatcher's own code cost
    for i, e in enumerate(rec.events):
        nested = sum(c["end"] - c["start"] for c in rec.events[i + 1:] if c["depth"] == e["depth"] + 1
                     and c["start"] >= e["start"] and c["end"] <= e["end"])
        exclusive[e["name"]] = exclusive.get(e["name"], 0.0) + e["end"] - e["start"] - nested
    usage = os.times()
    return {"compile_cpu": sum(e["end"] - e["start"] for e in top), "compiled": len(rec.events),
            "late": sorted({e["name"] for e in top if e["phase"] == "late"}),
            "late_cpu": sum(e["end"] - e["start"] for e in top if e["phase"] == "late"),
            "warm_wall": warm.get("wall", 0.0), "process_cpu": usage.user + usage.system, "main_cpu": main_cpu,
            "gate_cpu": gate.get("cpu"), "gate_wall": gate.get("wall"), "start_cpu": gate.get("start_cpu"),
            "phases": sorted(split.seconds.items(), key=lambda kv: -kv[1]) if split else [],
            "phases_by_dispatcher": split.by_owner if split else {},
            "inclusive": sorted(inclusive.items(), key=lambda kv: -kv[1]),
            "exclusive": sorted(exclusive.items(), key=lambda kv: -kv[1]),
            "events": [(e["name"], e["end"] - e["start"], e["depth"], e["outer"][-1] if e["outer"] else "", e["phase"],
                        e["args"])
                       for e in rec.events]}


def measure(scene: str, width: int, tree: Path, cached: int | None = None, phases: bool = False,
            ahead: bool = False) -> dict:
    """The worker's figures for `scene` on an empty cache; with `cached`, those of a second render at
    `cached` pixels wide on the cache the first filled, under "cached"."""
    with tempfile.TemporaryDirectory(prefix="compile_time_") as tmp:
        env = dict(os.environ, RAYTRACE_CACHE=str(Path(tmp) / "cache"), PYTHONPATH=str(tree))
        runs = []
        for w in [width] + ([cached] if cached else []):
            cmd = [sys.executable, __file__, "--worker", scene, "--width", str(w), "--out", tmp] + \
                (["--phases"] if phases and not runs else []) + (["--ahead"] if ahead and not runs else [])
            before, start = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
            proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
            wall, after = time.perf_counter() - start, resource.getrusage(resource.RUSAGE_CHILDREN)
            if proc.returncode != 0:
                raise SystemExit(f"{scene}: worker failed\n{proc.stderr[-3000:]}")
            runs.append(json.loads(proc.stdout.splitlines()[-1]))
            runs[-1].update(first_image_wall=wall, total_cpu=after.ru_utime + after.ru_stime - before.ru_utime
                            - before.ru_stime)
        if cached:
            runs[0]["cached"] = {k: runs[1][k] for k in ("main_cpu", "compiled", "compile_cpu")}
        return runs[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", help="comma-separated scene names (default: every bundled scene and the default)")
    ap.add_argument("--width", type=int, default=24, help="image width in pixels (default 24)")
    ap.add_argument("--profile", action="store_true", help="the top dispatchers by inclusive compile time")
    ap.add_argument("--top", type=int, default=8, help="dispatchers listed per scene with --profile")
    ap.add_argument("--tree", type=Path, default=ROOT, help="the checkout whose raytrace is measured")
    ap.add_argument("--before", type=Path, help="also measure this checkout, alternating with --tree (paired)")
    ap.add_argument("--runs", type=int, default=1, help="measurements per scene and checkout (default 1)")
    ap.add_argument("--cached", type=int, metavar="W",
                    help="then render each scene W pixels wide on the filled cache: its CPU s and compiles")
    ap.add_argument("--phases", action="store_true", help="the compile CPU seconds per phase (numba, LLVM)")
    ap.add_argument("--ahead", action="store_true", help="measure the compile worker's group (in one process)")
    ap.add_argument("--json", type=Path, help="also write the figures here")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker, args.width, args.out, args.phases, args.ahead)))
        return
    names = args.scenes.split(",") if args.scenes else scene_names(bool(os.environ.get("RAYTRACE_ASSETS")))
    if args.before or args.runs > 1 or args.cached:
        return paired(names, args)
    print(f"# tree {args.tree.resolve()}, width {args.width}, load {' '.join(f'{x:.1f}' for x in os.getloadavg())}, "
          f"{os.cpu_count()} cores")
    print("| scene | compile CPU s | compiled | late | warm-up wall s | process CPU s | first image wall s | "
          "total CPU s |")
    print("|---|---|---|---|---|---|---|---|")
    results = {}
    for name in names:
        r = results[name] = measure(name, args.width, args.tree, phases=args.phases, ahead=args.ahead)
        late = f"{len(r['late'])} ({r['late_cpu']:.1f} s: {', '.join(r['late'])})" if r["late"] else "0"
        print(f"| {name} | {r['compile_cpu']:.1f} | {r['compiled']} | {late} | {r['warm_wall']:.1f} | "
              f"{r['process_cpu']:.1f} | {r['first_image_wall']:.1f} | {r['total_cpu']:.1f} |", flush=True)
    print(f"# load after {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    if args.phases:
        for name, r in results.items():
            print(f"\n{name}: compile CPU s per phase, {sum(s for _, s in r['phases']):.1f} in all")
            for phase, sec in r["phases"]:
                print(f"  {sec:6.2f}  {phase}")
    if args.profile:
        for name, r in results.items():
            print(f"\n{name}: top dispatchers by compile CPU s, inclusive | exclusive")
            for (fn, s), (fx, x) in zip(r["inclusive"][:args.top], r["exclusive"][:args.top]):
                split = r.get("phases_by_dispatcher", {}).get(fx)
                split = f"  (numba {split.get('numb', 0.0):.2f}, LLVM {split.get('LLVM', 0.0):.2f})" if split else ""
                print(f"  {s:6.2f}  {fn:60s} | {x:6.2f}  {fx}{split}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))


def paired(names: list[str], args):
    """Per scene, `args.runs` rounds of (before, then tree): every run's compile CPU seconds, their
    median and the compiled specialisations, then every run's wall seconds to the first image and
    total CPU seconds (the worker's included) and their medians; with --cached, every run's render CPU seconds on the
    filled cache and what it compiled."""
    trees = ([("before", args.before)] if args.before else []) + [("now", args.tree)]
    print(f"# {', '.join(f'{k} {t.resolve()}' for k, t in trees)}; width {args.width}, {args.runs} runs each, "
          f"{os.cpu_count()} cores")
    cached = f" | cached render CPU s ({args.cached} px) | compiled" if args.cached else ""
    head = " | ".join(f"compile CPU s, {k} (runs) | median | compiled | first image wall s (runs) | median | "
                      f"total CPU s (runs) | median{cached}" for k, _ in trees)
    print(f"| scene | {head} |")
    print("|---" * (1 + (9 if args.cached else 7) * len(trees)) + "|")
    results = {}
    for name in names:
        runs = {k: [] for k, _ in trees}
        for _ in range(args.runs):
            for k, tree in trees:
                runs[k].append(measure(name, args.width, tree, args.cached, args.phases, args.ahead))
        results[name] = runs
        cells = []
        for k, _ in trees:
            cpu = statistics.median(r["compile_cpu"] for r in runs[k])
            each = ", ".join(f"{r['compile_cpu']:.1f}" for r in runs[k])
            cells.append(f"{each} | {cpu:.1f} | {runs[k][0]['compiled']}")
            for field in ("first_image_wall", "total_cpu"):
                cells.append(", ".join(f"{r[field]:.1f}" for r in runs[k]) + " | "
                             + f"{statistics.median(r[field] for r in runs[k]):.1f}")
            if args.cached:
                cells.append(", ".join(f"{r['cached']['main_cpu']:.2f}" for r in runs[k]) + " | "
                             + ", ".join(str(r["cached"]["compiled"]) for r in runs[k]))
        print(f"| {name} | {' | '.join(cells)} |", flush=True)
        if args.json:  # after every scene: a long run's figures so far
            args.json.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
