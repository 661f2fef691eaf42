"""Command line: render, compare, sweep, table1, seed002, describe, methods, diff, export, gallery (docs/cli.md).

User errors print one line on stderr and exit with status 2; nothing half-written stays on disk.
"""
from __future__ import annotations

import argparse
import contextlib
import copy
import os
import sys
import warnings
from pathlib import Path

import numpy as np

from .errors import UserError, counted
from .output.film import VIEWS

PAPER = '"An Analytical Solution to Single Scattering in Homogeneous Participating Media" (Pegoraro & Parker)'
DESCRIPTION = ("Render single scattering in participating media (fog, atmospheres, media inside shapes) to EXR and "
               f"PNG: the closed-form air-light of {PAPER}, and ray marching, quadrature and Monte Carlo to check it.")
COMMANDS = ("render", "describe", "methods", "diff", "compare", "sweep", "table1", "seed002", "export", "gallery",
            "assets")


def _method_param_flags():
    """Every parameter some method declares becomes a flag (--precision, --terms, --rtol, ...); the
    chosen method refuses a flag it does not read (a scene's [render] parameter it does not read,
    from the file or --set render.X, is ignored with one warning line instead)."""
    from .methods import registry

    flags = {}
    for m in registry().values():
        for name, p in m.params.items():
            flags.setdefault(name, p)
    return flags


def _add_scene_args(p):
    p.add_argument("scene", nargs="?", help="a scene file (TOML; glTF, Mitsuba 3 XML or pbrt-v4 are read too) or a "
                                            "bundled scene's name, e.g. box_room (default: the built-in default scene)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene value, e.g. --set medium.sigma_s=0.2 (repeatable)")
    p.add_argument("--camera", metavar="NAME",
                   help="the camera of a glTF scene to use, by its node's or its own name (default: the first)")


OPTION_HELP = {"spp": "samples per pixel (default: the scene's camera.spp)",
               "width": "image width in pixels (default: the scene's camera.width; alone, the height keeps the "
                        "camera's aspect)",
               "height": "image height in pixels (default: the scene's camera.height; alone, the width keeps the "
                         "camera's aspect)",
               "seed": "random seed of the stochastic methods (default 0)",
               "threads": "worker threads (default: all cores)"}


def _add_option_args(p):
    """--spp, --width, --height, --seed, --threads: the render options of compare and sweep."""
    for name, text in OPTION_HELP.items():
        p.add_argument(f"--{name}", type=int, help=text)


def _add_scheduler_arg(p):
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT|local:N",
                   help="render on a Dask cluster: a scheduler's address, or local:N for N local worker processes "
                        "(the same images; needs pip install -e '.[distributed]')")


def _cluster(args):
    """The Dask client of --scheduler, or None without it (Dask is then never imported)."""
    if not args.scheduler:
        return contextlib.nullcontext()
    try:
        from .rendering.distributed import connect
    except ImportError:
        raise UserError(f"--scheduler {args.scheduler}: needs Dask; install the extra: "
                        "pip install -e '.[distributed]'") from None
    return connect(args.scheduler, log=None if getattr(args, "quiet", False) else
                   lambda line: print(line, file=sys.stderr))


def _add_compare_shadows_arg(p):
    p.add_argument("--volumetric-shadows", action=argparse.BooleanOptionalAction,
                   help="shadowed air-light (light shafts) in every render (default: the scene's "
                        "render.volumetric_shadows, else off, unlike render)")


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr (SCENE_FORMAT.md), not usage + message."""

    def error(self, message):
        self.exit(2, f"error: {self.prog}: {message}; see `{self.prog} --help`\n")


def _command(sub, name: str, summary: str, details: str):
    """A subcommand: `summary` is its line in `render.py --help`; its own --help opens with the
    summary as a sentence, then `details`."""
    return sub.add_parser(name, help=summary, description=f"{summary[0].upper()}{summary[1:]}. {details}")


def build_parser():
    parser = _Parser(prog="render.py", description=DESCRIPTION,
                     epilog="Without a command, the arguments are render's: `render.py box_room` renders the bundled "
                            "scene box_room. `render.py COMMAND --help` lists a command's options; docs/cli.md has them all.")
    sub = parser.add_subparsers(dest="command")
    r = _command(sub, "render", "render a scene to EXR (and PNG)",
                 "A linear float32 EXR (with per-pixel error bounds) and an 8-bit PNG preview, with one air-light "
                 "method; every output path is checked before rendering and the files are written together.")
    _add_scene_args(r)
    r.add_argument("--method", help="air-light method (see `methods`), or auto: analytic where it takes the scene, else "
                                    "quadrature (default: the scene's render.method, else auto)")
    r.add_argument("--spp", type=int, help="samples per pixel (1 = the pixel centre)")
    r.add_argument("--width", type=int, help=OPTION_HELP["width"])
    r.add_argument("--height", type=int, help=OPTION_HELP["height"])
    r.add_argument("--seed", type=int, help="random seed of the stochastic methods (default 0)")
    r.add_argument("--out", help="output EXR (default out/<scene name>.exr, with a PNG beside it)")
    r.add_argument("--png", help="also write an 8-bit PNG preview here")
    r.add_argument("--exposure", type=float, help="PNG exposure in stops, each doubling the radiance (default: "
                                                  "automatic, the log-average luminance at middle grey)")
    r.add_argument("--view", choices=VIEWS, default="neutral",
                   help="PNG view: neutral (Khronos PBR Neutral, highlights roll off, lamps keep their hue; "
                        "default), aces (ACES 2.0 SDR, greys coloured lamps) or standard (the exact sRGB encode, "
                        "clipped at 1)")
    r.add_argument("--threads", type=int, help="worker threads (default: all cores)")
    r.add_argument("--crop", metavar="X0,Y0,X1,Y1",
                   help="render only this block of pixels (end exclusive), e.g. 100,50,101,51 for one pixel")
    r.add_argument("--aov", metavar="LAYERS",
                   help="extra EXR layers, comma-separated: depth (depth.Z, distance to the first hit), normal "
                        "(normal.X/Y/Z), albedo (albedo.R/G/B), lights (light0.R/G/B, ... one per light, and "
                        "emission.R/G/B: they sum to the image; the render takes about twice as long)")
    r.add_argument("--quiet", action="store_true", help="no progress bar or summary line")
    r.add_argument("--stats", action="store_true",
                   help="after the summary line, the method's statistics (also in the EXR header, stats.*)")
    r.add_argument("--display-server", metavar="HOST:PORT",
                   help="show the image in the tev viewer listening there as it renders (e.g. 127.0.0.1:14158, "
                        "tev's default); an unreachable viewer is a warning, the render goes on")
    r.add_argument("--max-memory", type=float, metavar="GIB",
                   help="memory budget of the image's arrays in GiB (default: 80%% of the machine's memory); a "
                        "larger image is refused up front with the figure and the fix")
    r.add_argument("--volumetric-shadows", action=argparse.BooleanOptionalAction,
                   help="shadowed air-light: light shafts behind occluders (default: the scene's "
                        "render.volumetric_shadows, else on)")
    r.add_argument("--shadow-spacing", type=float, metavar="RADIANS",
                   help="not read any more: the lit intervals are exact; accepted so that older scripts run")
    r.add_argument("--passes", type=int, help="stochastic methods: number of progressive passes")
    r.add_argument("--time-budget", type=float, help="stochastic methods: stop after this many seconds of rendering")
    r.add_argument("--target-error", type=float,
                   help="stochastic methods: stop when the estimated mean relative standard error falls to this")
    r.add_argument("--checkpoint", help="stochastic methods: checkpoint file, resumed when it exists "
                                        "(default: beside --out, <out>.ckpt.npz, when passes, a budget or a target are given)")
    r.add_argument("--checkpoint-interval", type=float, default=0.0,
                   help="least seconds between checkpoint writes (default 0: after every pass)")
    _add_scheduler_arg(r)
    for name, p in _method_param_flags().items():
        flag = f"--{name.replace('_', '-')}"
        if p.type is bool:
            r.add_argument(flag, dest=f"param_{name}", action="store_const", const=True, help=p.help)
        else:
            r.add_argument(flag, dest=f"param_{name}", type=p.type, metavar=name.upper(), help=p.help)
    c = _command(sub, "compare", "render several methods and a reference on the same samples; images, error maps "
                                 "and a table of time and error",
                 "Writes each method's EXR and PNG, its error map and compare.md / compare.json in --out.")
    _add_scene_args(c)
    c.add_argument("--methods", required=True,
                   help="comma-separated methods, each name or name:key=value:... (e.g. raymarch:steps=32)")
    c.add_argument("--reference", default="quadrature", help="reference method (default quadrature)")
    c.add_argument("--out", required=True, help="output folder")
    _add_option_args(c)
    c.add_argument("--exposure", type=float, help="PNG exposure in stops (default: automatic per image)")
    _add_compare_shadows_arg(c)
    _add_scheduler_arg(c)
    s = _command(sub, "sweep", "a scene over a grid of --set values x methods: one EXR and PNG per point and "
                               "method, a CSV/JSON table of time and error against the reference at each point",
                 "Every grid point is parsed before anything is rendered.")
    _add_scene_args(s)
    s.add_argument("--grid", action="append", required=True, metavar="KEY=V1,V2,...",
                   help="a grid axis: a scene key and its values (as --set values, split at top-level commas), "
                        "e.g. --grid medium.sigma_s=0.05,0.1 (repeatable: the grid is the product)")
    s.add_argument("--methods", required=True, help="comma-separated methods, as for compare")
    s.add_argument("--reference", default="quadrature", help="reference method (default quadrature)")
    s.add_argument("--out", required=True, help="output folder")
    _add_option_args(s)
    s.add_argument("--exposure", type=float, help="PNG exposure in stops (default: automatic per image)")
    _add_compare_shadows_arg(s)
    _add_scheduler_arg(s)
    t = _command(sub, "table1", f"Table 1 of {PAPER} on the paper's three scenes (time and error of each "
                                "method), with a report",
                 "The scenes Sibenik, bridge and conference (their meshes through RAYTRACE_ASSETS), unshadowed as in "
                 "the paper, then with volumetric shadows; images, error maps, report.md, report.json and report.html "
                 "with the paper's figures beside ours.")
    t.add_argument("--out", default="out/table1", help="output folder (default out/table1)")
    t.add_argument("--quick", action="store_true", help="small images and 1 spp (for CI)")
    t.add_argument("--seed", type=int, default=0, help=OPTION_HELP["seed"])
    t.add_argument("--threads", type=int, help=OPTION_HELP["threads"])
    t.add_argument("--shadows", choices=("quarter", "full", "off"), default="quarter",
                   help="the second table, with volumetric shadows: at a quarter of the width and height and "
                        "1 spp (default; the lit-interval search makes every shadowed render 5-40x slower), at "
                        "the full size, or off (with --quick it uses the quick images)")
    _add_scheduler_arg(t)
    e = _command(sub, "seed002", "the figures of the note on single scattering in a homogeneous slab (its "
                                 "abstract opens \"An analytical approach toward visualization of participating "
                                 "media\"): the air-light against the light's distance, and the measured error "
                                 "of its point-light approximation; CSV, report, plots",
                 "The note (an analytic single-scattering solution for homogeneous slabs, ocean and translucent "
                 "materials; its text carries no title, so it is named by its abstract) is the source of the media "
                 "inside shapes. Writes curves.csv, sweep.csv, report.md and, with matplotlib, PNG plots.")
    e.add_argument("--out", default="out/seed002", help="output folder (default out/seed002)")
    e.add_argument("--quick", action="store_true", help="13 light distances instead of 121 (for CI)")
    e.add_argument("--no-plots", action="store_true", help="CSV files and the report only (no matplotlib needed)")
    d = _command(sub, "describe", "print what a scene file parsed into",
                 "Camera, shapes and triangle count, bounds, lights, medium, background and [render].")
    _add_scene_args(d)
    _command(sub, "methods", "list the air-light methods and their parameters",
             "Each method with what it takes (lights, media, phase functions, media inside shapes), then its "
             "parameters with their defaults and allowed ranges.")
    x = _command(sub, "export", "write a scene for Mitsuba 3, pbrt-v4 or glTF 2.0 (docs/formats/)",
                 "What the format cannot express is refused in one line naming the key (or, with --approximate, "
                 "written as its closest form with a warning).")
    _add_scene_args(x)
    x.add_argument("--format", required=True, choices=("mitsuba", "pbrt", "gltf"), help="the file format to write")
    x.add_argument("--out", required=True, help="the file to write (meshes are written beside it or embedded)")
    x.add_argument("--approximate", action="store_true",
                   help="write what the format cannot express exactly as its closest form, with a warning naming it")
    g = _command(sub, "gallery", "every bundled scene (or those named) as a PNG preview with its own method "
                                 "and spp, at --width and the camera's aspect (README's gallery)",
                 "A scene whose meshes are not on RAYTRACE_ASSETS is skipped with a warning line.")
    g.add_argument("scenes", nargs="*", metavar="SCENE", help="bundled scene names (default: all of them)")
    g.add_argument("--out", default="docs/gallery", help="output folder, one NAME.png per scene (default docs/gallery)")
    g.add_argument("--width", type=int, default=960, help="image width in pixels (default 960)")
    g.add_argument("--threads", type=int, help="worker threads (default: all cores)")
    f = _command(sub, "diff", "error of TEST.exr against REF.exr, with an error map",
                 "Mean absolute, RMS, mean and maximum relative error; --bounds checks the difference against the "
                 "images' error_bound channels.")
    f.add_argument("test", help="the EXR to check")
    f.add_argument("ref", help="the reference EXR, of the same size")
    f.add_argument("--layer", metavar="NAME",
                   help="compare this output layer of both files instead of the image (depth, normal, albedo, "
                        "light0, ..., emission: written by render's output layers)")
    f.add_argument("--map", help="error map PNG (hue blue → red, scale on the image)")
    f.add_argument("--map-exr", help="absolute error per pixel as EXR")
    f.add_argument("--max", type=float, help="top of the error map's scale (default: the largest error)")
    f.add_argument("--bounds", type=float, metavar="K",
                   help="exit 1 unless |TEST - REF| <= K x (the sum of their error_bound channels) at every pixel "
                        "(docs/error_bounds.md)")
    a = _command(sub, "assets", "download the paper's meshes (Sibenik, the conference room) from their public "
                                "archives, check their SHA-256 sums and convert them for the bundled scenes",
                 "The files go into the first RAYTRACE_ASSETS folder, else the user's data folder, and each "
                 "archive's credit and licence is printed (docs/assets.md).")
    a.add_argument("names", nargs="*", metavar="NAME", help="archives to fetch: sibenik, conference (default: both)")
    a.add_argument("--folder", metavar="DIR", help="download into this folder instead (then add it to RAYTRACE_ASSETS)")
    a.add_argument("--mirror", metavar="URL", help="fetch the archives from this base URL, by their file names "
                                                   "(default: their public sources, or $RAYTRACE_ASSETS_MIRROR)")
    a.add_argument("--trust-unpinned", action="store_true",
                   help="also fetch an archive whose SHA-256 sum is not pinned (its sum is printed)")
    a.add_argument("--list", action="store_true", help="list the archives, their sources, sums, credits and licences")
    return parser


def cmd_assets(args):
    from .scene.download import assets, describe

    if args.list:
        print("\n".join(describe(args.folder)))
        return 0
    files = assets(args.names, folder=args.folder, mirror=args.mirror, trust_unpinned=args.trust_unpinned,
                   progress=sys.stderr.isatty(), note=lambda line: print(line, flush=True))
    print(f"{counted(len(files), 'file')} for the bundled scenes ready in {files[0].parents[1]}")
    return 0


def load(args):
    from .api import load as load_scene

    return load_scene(args.scene, args.overrides, args.camera)


def _given_params(args):
    """Method parameters given as flags (only those on the command line)."""
    return {k[len("param_"):]: v for k, v in vars(args).items() if k.startswith("param_") and v is not None}


def cmd_render(args):
    from .api import render
    from .output import film
    from .output.view import check_exposure

    check_exposure(args.exposure, "--exposure")
    scene = load(args)
    out = Path(args.out) if args.out else Path("out") / f"{scene.name}.exr"
    png = Path(args.png) if args.png else (None if args.out else out.with_suffix(".png"))
    if out.suffix.lower() != ".exr":
        raise UserError(f"--out {out}: must end in .exr; the image is written as linear float32 EXR")
    if png is not None and png.suffix.lower() != ".png":
        raise UserError(f"--png {png}: must end in .png; the preview is written as an 8-bit PNG")
    for p, flag in ((out, "--out"), (png, "--png")):
        if p is not None:
            film.check_writable(p, flag)
    progressive = args.passes or args.time_budget or args.target_error or args.checkpoint
    ckpt = Path(args.checkpoint) if args.checkpoint else (Path(str(out) + ".ckpt.npz") if progressive else None)
    if ckpt is not None:
        film.check_writable(ckpt, "--checkpoint")
    source = str(scene.path or "default scene")
    show = not args.quiet and sys.stderr.isatty()
    rows = (args.crop and _parse_crop(args.crop)) or None
    display = _display(args, scene, out.stem)
    bar = None
    if show:
        from tqdm import tqdm

        bar = tqdm(unit="tile", desc="render", file=sys.stderr, leave=False)

    def tile_done(done, total):  # tiles of the render, or of the Monte Carlo pass in flight
        if done == 1:
            bar.reset(total)
        bar.update(done - bar.n)

    passes_shown = []

    def report(n, err):
        if show:
            print(f"\rpass {n}: estimated mean relative error {err:.3e}", end="", file=sys.stderr, flush=True)
            passes_shown.append(n)

    try:
        with _cluster(args) as client:
            img = render(scene, args.method, client=client, **_option_args(args), crop=rows, observer=display,
                         volumetric_shadows=args.volumetric_shadows,
                         passes=args.passes, time_budget=args.time_budget, target_error=args.target_error,
                         checkpoint=ckpt, checkpoint_interval=args.checkpoint_interval,
                         progress=tile_done if bar is not None else None, on_pass=report, max_memory=args.max_memory,
                         notice=_notices(bar) if bar is not None else None, aov=args.aov,
                         **_given_params(args))
    except (KeyboardInterrupt, SystemError) as exc:
        if not from_interrupt(exc):
            raise
        if bar is not None:
            bar.close()  # before the line, which would otherwise follow the bar's
        # the checkpoint is named only once a pass (of this run or an earlier one) has written it
        print(("\n" if passes_shown else "") + f"interrupted: {source}"
              + (f"; the checkpoint {ckpt} keeps the finished passes, run the same command to resume"
                 if ckpt is not None and ckpt.is_file() else "; nothing was written"), file=sys.stderr)
        return 130
    finally:
        if bar is not None:
            bar.close()
        if display is not None:
            display.close()
    outputs = [out] + ([png] if png is not None else [])
    with film.folders_for(outputs):  # missing folders are created now, and removed again if the save fails
        img.save(*outputs, exposure=args.exposure, view=args.view)  # both or neither
    if not args.quiet:
        print(_summary(scene, img, args.crop if rows else None, [out] + ([png] if png else [])))
    if rows is not None and img.array.shape[:2] == (1, 1):
        print(_pixel(img, rows))
    if args.stats:
        for k, v in img.stats.items():
            print(f"  {k}: {v:.6g}" if isinstance(v, float) else f"  {k}: {v}")
    return 0


def _summary(scene, img, crop, outputs) -> str:
    """The render's one line: scene, size, spp, method (auto's choice), times, outputs, and the share of
    pixels without a finite error bound where there are any."""
    cam = scene.camera
    size = f"{cam.width}x{cam.height}" + (f" (crop {crop})" if crop else "")
    note = img.bound_note()
    return (f"{scene.name}: {size}, {cam.spp} spp, method {img.method_label} in {img.seconds:.2f} s "
            f"(+{img.compile_seconds:.2f} s compile) → {', '.join(map(str, outputs))}" + (f"; {note}" if note else ""))


def _pixel(img, crop) -> str:
    """The value of a one-pixel --crop and its error bound (for a stochastic method: the standard
    error, plus any bound), as stdout prints it."""
    from .methods import registry

    value, bound = img.array[0, 0], img.error_bound[0, 0]
    # a deterministic method's area-lit penumbrae carry a variance too; its error_bound is still a bound
    what = "standard error" if registry()[img.method].stochastic else "error bound"
    return (f"pixel ({crop[0]}, {crop[1]}): RGB {' '.join(f'{v:.9g}' for v in value)}, "
            f"{what} {' '.join(f'{b:.9g}' for b in bound)}")


def _notices(bar):
    """Where a render's one-line notes (the kernels' compile) go: stderr above the progress bar,
    so only on a terminal and without --quiet, as the bar (the summary line gives the compile time)."""
    return lambda line: bar.write(line, file=sys.stderr)


def _display(args, scene, name):
    """The tev display of --display-server showing the image `name` (None without the flag)."""
    if not args.display_server:
        return None
    from .api import image_size, render_options
    from .output.tev import TevDisplay, parse_address

    parse_address(args.display_server)  # a badly formed address is refused before --width is looked at
    render_options(None, width=args.width, height=args.height)  # refuses a size that is not positive
    return TevDisplay.open(args.display_server, name, *image_size(scene.camera, args.width, args.height))


def _parse_crop(text):
    try:
        x0, y0, x1, y1 = (int(v) for v in text.split(","))
    except ValueError:
        raise UserError(f"--crop {text}: expected four integers X0,Y0,X1,Y1, e.g. --crop 100,50,101,51") from None
    return x0, y0, x1, y1


def _option_args(args):
    """The render options every rendering command takes (spp, size, seed, threads), as keywords."""
    return {k: getattr(args, k) for k in ("spp", "width", "height", "seed", "threads")}


def cmd_compare(args):
    from .api import executor, render_options
    from .experiments.compare import compare, parse_spec
    from .output.view import check_exposure
    from .rendering import renderer

    check_exposure(args.exposure, "--exposure")
    scene = load(args)
    options = render_options(scene, **_option_args(args), volumetric_shadows=args.volumetric_shadows)
    specs = [parse_spec(s) for s in args.methods.split(",") if s.strip()]
    reference = parse_spec(args.reference)
    out = _folder(args.out)
    with _cluster(args) as client:
        compare(renderer.prepare(scene), specs, reference, out, options, executor(options, client), args.exposure)
    print(f"wrote {out / 'compare.md'}")
    return 0


def _folder(path):
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out}: exists and is not a folder; choose a folder path")
    return out


def cmd_sweep(args):
    from .api import executor, load as load_scene, render_options
    from .experiments.compare import parse_spec
    from .experiments.sweep import grid_points, parse_axis, sweep
    from .output.view import check_exposure

    check_exposure(args.exposure, "--exposure")
    axes = [parse_axis(g) for g in args.grid]
    specs = [parse_spec(s) for s in args.methods.split(",") if s.strip()]
    reference = parse_spec(args.reference)
    points = []
    for where in grid_points(axes):  # every point parsed before anything is rendered or written
        scene = load_scene(args.scene, args.overrides + [f"{k}={v}" for k, v in where.items()], args.camera)
        options = render_options(scene, **_option_args(args), volumetric_shadows=args.volumetric_shadows)
        points.append((where, scene, options))  # each point its own options (a grid may set [render] keys)
    out = _folder(args.out)
    with _cluster(args) as client:
        sweep(points, specs, reference, out, executor(options, client), args.exposure)
    print(f"wrote {out / 'sweep.csv'} and {out / 'sweep.json'}")
    return 0


def cmd_table1(args):
    from .api import executor, render_options
    from .experiments import table1

    # the paper's table is unshadowed; table1.run adds the shadowed one itself
    options = render_options(None, seed=args.seed, threads=args.threads, volumetric_shadows=False)
    out = _folder(args.out)
    with _cluster(args) as client:
        table1.run(out, args.quick, options, shadows=args.shadows, executor=executor(options, client))
    return 0


def cmd_seed002(args):
    from .experiments import seed002

    out = _folder(args.out)
    seed002.run(out, plots=not args.no_plots, ls=seed002.QUICK_GRID if args.quick else seed002.L_GRID)
    print(f"wrote {out / 'report.md'}, {out / 'curves.csv'} and {out / 'sweep.csv'}")
    return 0


def cmd_describe(args):
    from .lights import describe as light_text
    from .media.phase import NAMES
    from .scene.meshes import scene_triangles

    scene = load(args)
    cam = scene.camera
    tris, _ = scene_triangles(scene)
    print(f"scene {scene.name!r} ({scene.path or 'built-in'})")
    print(f"camera: {cam.type}, {cam.width}x{cam.height}, {cam.spp} spp, position {cam.position.tolist()}, "
          f"look_at {cam.look_at.tolist()}, up {cam.up.tolist()}" + (f", fov {cam.fov}" if cam.type == "perspective" else ""))
    kinds = {}
    for s in scene.shapes:
        kinds[s.kind] = kinds.get(s.kind, 0) + 1
    print(f"shapes: {len(scene.shapes)} ({', '.join(f'{k}: {v}' for k, v in kinds.items())}), "
          f"{counted(len(tris), 'triangle')} (zero-area triangles left out)")
    if len(tris):
        pts = tris.reshape(-1, 3)
        print(f"bounds: {pts.min(axis=0).round(4).tolist()} to {pts.max(axis=0).round(4).tolist()}")
    for i, s in enumerate(scene.shapes):
        if s.interior is not None:
            m = s.interior
            print(f"shape[{i}].interior: sigma_a {m.sigma_a.tolist()}, sigma_s {m.sigma_s.tolist()}, phase "
                  f"{NAMES[m.phase]}{f' g={m.g}' if NAMES[m.phase] == 'hg' else ''}, ior {m.ior:g}")
    for i, light in enumerate(scene.lights):
        print(f"light[{i}]: {light_text(light)}")
    for line in scene.medium.describe():
        print(line)
    print(f"background: {scene.background.tolist()}")
    if scene.render:
        print(f"render: {scene.render}")
    return 0


def cmd_export(args):
    from . import io
    from .api import scene_dict
    from .scene.format import scene_from_dict

    raw, source, path = scene_dict(args.scene, args.overrides, args.camera)
    scene_from_dict(copy.deepcopy(raw), source, path)  # the scene must be valid before anything is written
    for written in io.export(raw, args.format, Path(args.out), source, args.approximate):
        print(f"wrote {written}")
    return 0


def cmd_gallery(args):
    from .gallery import render_gallery

    written = render_gallery(Path(args.out), args.width, args.scenes, note=lambda line: print(line, flush=True),
                             threads=args.threads)
    print(f"wrote {counted(len(written), 'image')} to {args.out}")
    return 0


def cmd_methods(args):
    from .methods import registry

    for m in registry().values():
        print(f"{m.name}: {m.summary}")
        print(f"    {m.supports.describe()}")
        for name, p in m.params.items():
            print(f"    --{name.replace('_', '-')} (default {p.default!r}, {p.rule()}): {p.help}")
    print("render options (every method): --spp, --seed, --threads, --crop, --[no-]volumetric-shadows "
          "(render.volumetric_shadows, on by default: the air-light over each light's lit intervals, which are "
          "exact: docs/exact_shadows.md)")
    return 0


def cmd_diff(args):
    from .output import film, metrics

    test, _ = film.read_exr(args.test)
    ref, _ = film.read_exr(args.ref)
    if args.layer is not None:
        if args.bounds is not None:
            raise UserError(f"--bounds with --layer {args.layer}: the error_bound channels bound the image, not its "
                            "layers; leave one out")
        test, ref = (film.read_exr_layer(p, args.layer) for p in (args.test, args.ref))
    if test.shape != ref.shape:
        raise UserError(f"{args.test} is {test.shape[1]}x{test.shape[0]} but {args.ref} is "
                        f"{ref.shape[1]}x{ref.shape[0]}; render both at the same --width and --height")
    e = metrics.errors(test, ref)
    for k, v in e.items():
        print(f"{k}: {v:.6e}")
    failed = False
    if args.bounds is not None:
        if not args.bounds > 0:
            raise UserError(f"--bounds {args.bounds}: must be a positive factor, e.g. --bounds 1")
        bounds = [film.read_exr_channels(p, "error_bound") for p in (args.test, args.ref)]
        for path, b in zip((args.test, args.ref), bounds):
            if b is None:
                raise UserError(f"{path}: no error_bound.R/G/B channels; render it again with render.py render")
        check = metrics.bound_check(test, ref, *bounds, args.bounds)
        for k, v in check.items():
            print(f"{k}: {v:.6e}" if isinstance(v, float) else f"{k}: {v}")
        failed = check["pixels_over_bounds"] > 0
    if args.map or args.map_exr:
        rgb, err, vmax = metrics.error_map(test, ref, args.max)
        if args.map:
            film.write_png(args.map, rgb)
        if args.map_exr:
            film.write_exr(args.map_exr, np.repeat(err[..., None], 3, axis=2), {"scale_max": vmax})
    return 1 if failed else 0


def one_line_warning(message, category, filename, lineno, line=None) -> str:
    """A warning as the command line prints it: `warning: <message>` on one line, without the source
    line Python adds by default."""
    return "warning: " + " ".join(str(message).split()) + "\n"


@contextlib.contextmanager
def _one_line_warnings():
    """Every warning (importers' notes, --approximate, the live display's, scene defaults ignored)
    printed as one line on stderr. The format is replaced rather than `showwarning`, so that a
    caller recording warnings (warnings.catch_warnings(record=True), pytest.warns) still gets them."""
    saved, warnings.formatwarning = warnings.formatwarning, one_line_warning
    try:
        yield
    finally:
        warnings.formatwarning = saved


def from_interrupt(exc: BaseException) -> bool:
    """Whether `exc` is Ctrl-C: a KeyboardInterrupt, or an exception raised because of one (numba
    turns an interrupt that arrives while a cached kernel's constants are unpickled into a
    SystemError whose cause is the KeyboardInterrupt)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv:
        argv = ["render"]
    elif argv[0] not in COMMANDS and argv[0] not in ("-h", "--help"):
        argv.insert(0, "render")
    args = build_parser().parse_args(argv)
    handlers = {"render": cmd_render, "describe": cmd_describe, "methods": cmd_methods, "diff": cmd_diff,
                "compare": cmd_compare, "sweep": cmd_sweep, "table1": cmd_table1,
                "seed002": cmd_seed002, "export": cmd_export, "gallery": cmd_gallery, "assets": cmd_assets}
    try:
        with _one_line_warnings():
            return handlers[args.command](args)
    except UserError as exc:
        lines = exc.lines or [" ".join(str(exc).split("\n"))]  # one line, or a file's problems one a line
        print("\n  ".join(["error: " + lines[0], *lines[1:]]), file=sys.stderr)
        return 2
    except (KeyboardInterrupt, SystemError) as exc:
        if not from_interrupt(exc):
            raise
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into a command that stopped reading (e.g. head)
        return 0


def run() -> int:
    """The process's entry point (render.py, the `raytrace` script): `main`'s exit status; after
    Ctrl-C (130) the process ends at once, its streams flushed, without finalizing the interpreter
    around the tiles still running in the renderer's daemon threads (that took ~1 s on the larger
    scenes). Nothing is pending then: an interrupted render has written nothing but its checkpoint."""
    status = main()
    if status == 130:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
    return status
