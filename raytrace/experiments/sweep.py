"""A scene over a grid of scene values x methods: one EXR per grid point and method, and a table
(CSV and JSON) of render time and error against the reference rendered at the same point.

A grid axis is ``KEY=V1,V2,...`` (values as for --set, split at the commas outside brackets, braces
and quotes), e.g. ``medium.sigma_s=0.05,0.1,0.2`` or ``medium.phase="isotropic",{type="hg",g=0.5}``;
the grid is the product of its axes, in the order given.
"""
from __future__ import annotations

import csv
import io
import itertools
import json
from pathlib import Path

from .. import film, metrics
from ..errors import UserError
from ..options import RenderOptions
from ..renderer import prepare
from ..scene.format import Scene, parse_override
from .compare import MethodSpec, render_spec, safe_name

FIELDS = ("method", "seconds", "compile_seconds", "mean_abs", "mean_rel", "max_rel", "rms")


def split_values(text: str) -> list[str]:
    """`text` split at the commas outside [], {} and quotes."""
    parts, depth, quote, cur = [], 0, None, ""
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
            continue
        cur += ch
    return parts + [cur]


def parse_axis(text: str) -> tuple[str, list[str]]:
    """``KEY=V1,V2`` -> (KEY, ["V1", "V2"]), each value checked as a --set value."""
    if "=" not in text:
        raise UserError(f"--grid {text}: expected KEY=V1,V2,...; for example --grid medium.sigma_s=0.1,0.2")
    key, values = text.split("=", 1)
    values = [v.strip() for v in split_values(values)]
    if not key.strip() or not all(values):
        raise UserError(f"--grid {text}: an empty key or value; write e.g. --grid medium.sigma_s=0.1,0.2")
    for v in values:
        parse_override(f"{key.strip()}={v}", "--grid")
    return key.strip(), values


def grid_points(axes: list[tuple[str, list[str]]]) -> list[dict]:
    """Every combination of the axes' values, the last axis varying fastest: [{key: value}, ...]."""
    keys = [k for k, _ in axes]
    return [dict(zip(keys, values)) for values in itertools.product(*[v for _, v in axes])]


def sweep(points: list[tuple[dict, Scene]], specs: list[MethodSpec], reference: MethodSpec, out: Path,
          options: RenderOptions = RenderOptions(), executor=None, log=print) -> list[dict]:
    """Render every grid point (its values and parsed scene) with the reference and every method,
    with `options` on `executor` (renderer.render's); write p<i>_<method>.exr per point and
    sweep.csv / .json."""
    keys = list(points[0][0]) if points else []
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for i, (where, scene) in enumerate(points):
        prep = prepare(scene)
        ref = render_spec(prep, reference, options, executor)
        header = {"scene": scene.name, "spp": scene.camera.spp, "seed": options.seed,
                  "grid": " ".join(f"{k}={v}" for k, v in where.items())}
        film.write_exr(out / f"p{i:03d}_reference.exr", ref.image, {**header, "method": reference.label})
        for spec in specs:
            r = render_spec(prep, spec, options, executor)
            extra = {f"variance.{c}": r.variance[..., j] for j, c in enumerate("RGB")} if r.variance is not None else {}
            film.write_exr(out / f"p{i:03d}_{safe_name(spec.label)}.exr", r.image,
                           {**header, "method": spec.label, "render_seconds": r.seconds}, extra)
            e = metrics.errors(r.image, ref.image)
            rows.append({"point": i, **where, "method": spec.label, "seconds": r.seconds,
                         "compile_seconds": r.compile_seconds, **{k: e[k] for k in FIELDS[3:]}})
            log(f"p{i:03d} {header['grid']} {spec.label}: {r.seconds:.3f} s, mean rel {e['mean_rel']:.3e}")
    buf = io.StringIO()
    writer = csv.DictWriter(buf, ["point", *keys, *FIELDS], lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    (out / "sweep.csv").write_text(buf.getvalue())
    (out / "sweep.json").write_text(json.dumps({"scene": points[0][1].name if points else None, "seed": options.seed,
                                                "reference": reference.label, "rows": rows}, indent=2, default=float))
    return rows
