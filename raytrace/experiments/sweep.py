"""A scene over a grid of scene values x methods: one EXR and its PNG preview per grid point and
method, and a table (CSV and JSON) of render time and error against the reference rendered at the
same point.

A grid axis is ``KEY=V1,V2,...`` (values as for --set, split at the commas outside brackets, braces
and quotes), e.g. ``medium.sigma_s=0.05,0.1,0.2`` or ``medium.phase="isotropic",{type="hg",g=0.5}``;
the grid is the product of its axes, in the order given. The CSV is plain: a grid value that is a
string, number or boolean is written as itself (``isotropic``, not ``"isotropic"``), an array or
table as given; times and errors with 6 significant digits. The JSON has the values parsed, and
the numbers in full.
"""
from __future__ import annotations

import csv
import io
import itertools
import json
from pathlib import Path

from ..errors import UserError
from ..options import RenderOptions
from ..output import film, metrics
from ..rendering.renderer import prepare
from ..scene.format import Scene, parse_override
from .compare import MethodSpec, check_specs, render_spec, safe_name, summary

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


def grid_value(key: str, text: str):
    """The value of a grid point's `text` (as --set reads it)."""
    return parse_override(f"{key}={text}", "--grid")[1]


def plain(key: str, text: str) -> str:
    """A grid value as the CSV writes it: a string, number or boolean as itself, else `text`."""
    value = grid_value(key, text)
    if isinstance(value, bool):
        return str(value).lower()
    return str(value) if isinstance(value, (str, int, float)) else text


def _save(path: Path, image, header: dict, variance, exposure):
    """`path` (.exr) and its PNG preview beside it, written together."""
    extra = {f"variance.{c}": variance[..., j] for j, c in enumerate("RGB")} if variance is not None else {}
    film.write_together([(path, film.exr_writer(image, header, extra)),
                         (path.with_suffix(".png"), film.png_writer(film.tonemap(image, exposure)))])


def sweep(points: list[tuple[dict, Scene, RenderOptions]], specs: list[MethodSpec], reference: MethodSpec, out: Path,
          executor=None, exposure: float | None = None, log=print) -> list[dict]:
    """Render every grid point (its values as given, its parsed scene and its render options) with
    the reference and every method on `executor` (renderer.render's); write p<i>_<method>.exr and
    .png (`exposure` in stops, None: automatic) per point, sweep.csv and sweep.json. Returns the
    JSON's rows. Every point's scene is prepared and every method checked on it first
    (compare.check_specs): bad input writes nothing."""
    keys = list(points[0][0]) if points else []
    preps = [prepare(scene) for _, scene, _ in points]  # kept for the renders: each point is prepared once
    for prep, (_, _, options) in zip(preps, points):
        check_specs(prep, specs, reference, options)
    out.mkdir(parents=True, exist_ok=True)
    rows, lines = [], []
    for i, (prep, (where, scene, options)) in enumerate(zip(preps, points)):
        ref = render_spec(prep, reference, options, executor)
        header = {"scene": scene.name, "spp": scene.camera.spp, "seed": options.seed,
                  "grid": " ".join(f"{k}={v}" for k, v in where.items())}
        _save(out / f"p{i:03d}_reference.exr", ref.image, {**header, "method": reference.label}, None, exposure)
        for spec in specs:
            r = render_spec(prep, spec, options, executor)
            _save(out / f"p{i:03d}_{safe_name(spec.label)}.exr", r.image,
                  {**header, "method": spec.label, "render_seconds": r.seconds}, r.variance, exposure)
            e = metrics.errors(r.image, ref.image)
            numbers = {"seconds": r.seconds, "compile_seconds": r.compile_seconds, **{k: e[k] for k in FIELDS[3:]}}
            rows.append({"point": i, **{k: grid_value(k, v) for k, v in where.items()}, "method": spec.label,
                         **numbers})
            lines.append({"point": i, **{k: plain(k, v) for k, v in where.items()}, "method": spec.label,
                          **{k: f"{v:.6g}" for k, v in numbers.items()}})
            log(f"p{i:03d} {header['grid']} {spec.label}: {r.seconds:.3f} s, {summary(e)}")
    buf = io.StringIO()
    writer = csv.DictWriter(buf, ["point", *keys, *FIELDS], lineterminator="\n")
    writer.writeheader()
    writer.writerows(lines)
    (out / "sweep.csv").write_text(buf.getvalue())
    (out / "sweep.json").write_text(json.dumps({"scene": points[0][1].name if points else None,
                                                "seed": points[0][2].seed if points else None,
                                                "reference": reference.label, "rows": rows}, indent=2, default=float))
    return rows
