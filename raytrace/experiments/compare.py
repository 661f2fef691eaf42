"""Render one scene with several methods and a reference on the same camera samples; tabulate
time and error per method and write every image, its error map and a Markdown + JSON table.

A method is given as ``name`` or ``name:key=value:key=value`` (for example ``raymarch:steps=32``),
so one method can appear with several settings.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..methods import get_method
from ..options import RenderOptions
from ..output import film, metrics
from ..rendering.progressive import render_progressive
from ..rendering.renderer import Prepared, RenderResult, check, render
from ..scene.format import parse_override


@dataclass
class MethodSpec:
    label: str
    name: str
    params: dict


def parse_spec(text: str) -> MethodSpec:
    parts = [p for p in text.strip().split(":") if p]
    if not parts:
        raise UserError(f"--methods {text!r}: empty method; write e.g. raymarch:steps=32")
    name, params = parts[0], {}
    method = get_method(name)
    for p in parts[1:]:
        if "=" not in p:
            raise UserError(f"--methods {text}: {p!r} is not key=value; write e.g. {name}:key=value")
        k, v = p.split("=", 1)
        if k not in method.params:
            raise UserError(f"--methods {text}: {name} has no parameter {k!r}; it takes {', '.join(method.params)}")
        params[k] = parse_override(f"{k}={v}", "--methods")[1]
    return MethodSpec(text.strip(), name, params)


def check_specs(prep: Prepared, specs: list[MethodSpec], reference: MethodSpec, options: RenderOptions):
    """The reference and every method checked on the scene (`renderer.check`, each named by its flag),
    so that bad input is refused before anything is rendered or written."""
    check(prep, reference.name, reference.params, options, f"--reference {reference.label}")
    for spec in specs:
        check(prep, spec.name, spec.params, options, f"--methods {spec.label}")


def render_spec(prep: Prepared, spec: MethodSpec, options: RenderOptions = RenderOptions(),
                executor=None) -> RenderResult:
    """One render of `spec` with `options` (one pass for a stochastic method) on `executor`
    (renderer.render's; default a thread pool)."""
    if get_method(spec.name).stochastic:
        return render_progressive(prep, spec.name, spec.params, replace(options, passes=1), executor, spec.label)
    return render(prep, spec.name, spec.params, options, executor, spec.label)


def safe_name(label: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in label)


def compare(prep: Prepared, specs: list[MethodSpec], reference: MethodSpec, out: Path,
            options: RenderOptions = RenderOptions(), executor=None, exposure=None, log=print) -> list[dict]:
    """Render the reference and every method with `options` on `executor` (renderer.render's);
    write images, error maps and compare.md/.json in `out`. Every method and parameter is checked
    on the scene first (`check_specs`): bad input writes nothing."""
    check_specs(prep, specs, reference, options)
    out.mkdir(parents=True, exist_ok=True)
    ref = render_spec(prep, reference, options, executor)
    header = {"scene": prep.scene.name, "spp": prep.scene.camera.spp, "seed": options.seed}
    film.write_exr(out / "reference.exr", ref.image, {**header, "method": reference.label})
    film.write_png(out / "reference.png", film.tonemap(ref.image, exposure))
    results = [(spec, render_spec(prep, spec, options, executor)) for spec in specs]
    vmax = metrics.shared_scale([r.image for _, r in results], ref.image)
    rows = []
    for spec, r in results:
        name = safe_name(spec.label)
        extra = {}
        if r.variance is not None:
            extra = {f"variance.{c}": r.variance[..., i] for i, c in enumerate("RGB")}
        film.write_exr(out / f"{name}.exr", r.image, {**header, "method": spec.label, "render_seconds": r.seconds}, extra)
        film.write_png(out / f"{name}.png", film.tonemap(r.image, exposure))
        rgb, _, _ = metrics.error_map(r.image, ref.image, vmax)
        film.write_png(out / f"{name}_error.png", rgb)
        e = metrics.errors(r.image, ref.image)
        row = {"method": spec.label, "seconds": r.seconds, "compile_seconds": r.compile_seconds, **e,
               "negative_pixels": int(np.sum(r.image < 0)), "stats": {k: v for k, v in r.stats.items()}}
        rows.append(row)
        log(f"{spec.label}: {r.seconds:.3f} s, {summary(e)}")
    table = {"scene": prep.scene.name, "reference": reference.label, "reference_seconds": ref.seconds,
             "error_map_scale": vmax, "methods": rows}
    (out / "compare.json").write_text(json.dumps(table, indent=2, default=float))
    (out / "compare.md").write_text(markdown_table(table))
    return rows


def summary(e: dict) -> str:
    """A method's errors as the log line gives them: the means beside the maximum and the RMS (a
    mean alone can hide a few very wrong pixels), as the table's columns."""
    return (f"mean abs {e['mean_abs']:.3e}, mean rel {e['mean_rel']:.3e}, max rel {e['max_rel']:.3e}, "
            f"RMS {e['rms']:.3e}")


def markdown_table(table: dict) -> str:
    lines = [f"# {table['scene']}: methods against `{table['reference']}` "
             f"({table['reference_seconds']:.2f} s)\n",
             f"Error maps share one scale: blue = 0, red = {table['error_map_scale']:.3g} and above (absolute "
             "error; the 99th percentile of the pooled errors of the methods that did not diverge).\n",
             "| method | time (s) | mean abs. error | mean abs. / mean ref. | mean rel. error | max rel. error "
             "| RMS | negative pixels |",
             "|---|---|---|---|---|---|---|---|"]
    for r in table["methods"]:
        lines.append(f"| {r['method']} | {r['seconds']:.3f} | {r['mean_abs']:.3e} | {r['mean_abs_over_mean_ref']:.3e} "
                     f"| {r['mean_rel']:.3e} | {r['max_rel']:.3e} | {r['rms']:.3e} | {r['negative_pixels']} |")
    return "\n".join(lines) + "\n"
