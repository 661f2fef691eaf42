"""Progressive rendering of stochastic methods, with atomic checkpoints and exact resume.

Pass p renders the whole image with the seed `pass_seed(seed, p)`; the image is the mean of the
passes, its variance the sum of the passes' variances over passes² and its error bound (of all but
the estimator's noise, error_bounds.py) the mean of the passes' bounds. Passes are accumulated in
order, so a render interrupted (Ctrl-C, crash, machine restart) and resumed from its checkpoint
equals an uninterrupted one with the same seed and number of passes, bit for bit. Rendering stops
after `passes` passes, when `time_budget` seconds (counted over all sessions) are spent, or when
the estimated mean relative standard error of the pixels falls to `target_error`, whichever
comes first. The checkpoint is written after every pass (or at most every `checkpoint_interval`
seconds) and on Ctrl-C, so a crash loses at most the pass in flight; it is kept afterwards, so
the same command with a larger budget continues where the last one stopped.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from .. import error_bounds
from ..errors import UserError
from ..options import RenderOptions
from .renderer import Prepared, RenderResult, render

GOLDEN = 0x9E3779B97F4A7C15


def pass_seed(seed: int, p: int) -> int:
    return (seed + p * GOLDEN) % (1 << 64)


def _feed(h, obj):
    """Hash `obj` by content: dataclasses field by field, arrays by dtype, shape and bytes."""
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            h.update(f.name.encode())
            _feed(h, getattr(obj, f.name))
    elif isinstance(obj, np.ndarray):
        h.update(f"{obj.dtype}{obj.shape}".encode() + np.ascontiguousarray(obj).tobytes())
    elif isinstance(obj, (list, tuple)):
        h.update(f"[{len(obj)}".encode())
        for x in obj:
            _feed(h, x)
    else:
        h.update(json.dumps(obj, sort_keys=True, default=str).encode())


def fingerprint(prep: Prepared, method: str, params: dict, seed: int) -> str:
    """What a checkpoint must match to be resumed: the camera, every light and medium (the shapes'
    interiors too) by content, the triangles, reflectances and shading normals, the method, its
    parameters, the seed."""
    h = hashlib.sha256()
    scene = prep.scene
    _feed(h, {"method": method, "params": params, "seed": seed})
    _feed(h, [scene.camera, scene.lights, scene.medium, [s.interior for s in scene.shapes], scene.background])
    for a in (prep.accel.triangles, prep.reflectance, prep.corner_normals):
        if a is not None:  # no shading normals: all flat
            _feed(h, a)
    return h.hexdigest()


def _save(path: Path, state: dict):
    path.parent.mkdir(parents=True, exist_ok=True)  # the first save creates a missing folder
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".npz", dir=path.parent)
    os.close(fd)
    try:
        np.savez(tmp, **state)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _load(path: Path, fp: str):
    if not path.is_file():
        return None
    try:
        with np.load(path) as z:
            if str(z["fingerprint"]) != fp:
                raise UserError(f"{path}: checkpoint of a different render (scene, method, parameters or seed "
                                "differ); delete it or choose another --checkpoint")
            return {k: z[k] for k in z.files}
    except (OSError, ValueError, KeyError):
        raise UserError(f"{path}: unreadable checkpoint; delete it to start afresh") from None


BAND = 1 << 20  # values per band of `mean_relative_error`: its temporaries stay small (issue 15)


def mean_relative_error(total, var_total, passes) -> float:
    """Estimated mean relative standard error of the pixel estimates (floored at 1e-3 of the mean),
    computed in bands of rows."""
    total, var_total = total.reshape(-1), var_total.reshape(-1)
    if not total.size:
        return float("nan")
    bands = [slice(i, i + BAND) for i in range(0, total.size, BAND)]
    floor = max(1e-3 * sum(float(np.abs(total[b]).sum()) for b in bands) / total.size / passes, 1e-300)
    return sum(float((np.sqrt(var_total[b]) / passes / np.maximum(np.abs(total[b] / passes), floor)).sum())
               for b in bands) / total.size


def render_progressive(prep: Prepared, method_name: str, params: dict, options: RenderOptions = RenderOptions(),
                       executor=None, source: str = "render") -> RenderResult:
    """Render passes until one of `options`' stopping rules holds (passes, time_budget, target_error;
    one pass when none is given), resuming from and saving to `options.checkpoint`.
    `options.on_pass(passes, error_estimate)` reports each pass, `options.progress(done, total)` the
    tiles of the pass in flight and `options.observer(y0, y1, x0, x1, block)` each block of rows of
    the pass in flight as soon as it is final, as the mean of the passes so far (the last pass's
    blocks are the final image). Every pass runs on `executor` (renderer.render's); the checkpoint is
    the same on one machine or a cluster, so a render resumes on either."""
    passes, time_budget, target_error = options.passes, options.time_budget, options.target_error
    checkpoint, crop = options.checkpoint, options.crop
    if passes is None and time_budget is None and target_error is None:
        passes = 1
    fp = fingerprint(prep, method_name, {**params, "crop": crop, "volumetric_shadows": options.volumetric_shadows}, options.seed)
    state = _load(checkpoint, fp) if checkpoint else None
    if state is None:
        cam = prep.scene.camera
        x0, y0, x1, y1 = crop or (0, 0, cam.width, cam.height)
        state = {"fingerprint": np.array(fp), "total": np.zeros((y1 - y0, x1 - x0, 3)),
                 "var_total": np.zeros((y1 - y0, x1 - x0, 3)), "bound_total": np.zeros((y1 - y0, x1 - x0, 3), np.float32),
                 "passes": np.array(0),
                 "elapsed": np.array(0.0), "compile": np.array(0.0)}
    if "bound_total" not in state:  # a checkpoint written before the bounds: its passes' are unknown
        state["bound_total"] = np.full(state["total"].shape, np.inf, np.float32)
    done = int(state["passes"])
    elapsed = float(state["elapsed"])
    last_save = time.perf_counter()
    result = None
    layers, layer_passes = {}, 0  # the output layers' sums over this call's passes (not checkpointed: api.py
    # refuses layers with the progressive options)

    def finished():
        if done == 0:
            return False
        if passes is not None and done >= passes:
            return True
        if time_budget is not None and elapsed >= time_budget:
            return True
        return target_error is not None and mean_relative_error(state["total"], state["var_total"], done) <= target_error

    ox, oy = crop[:2] if crop else (0, 0)

    def observe(y0, y1, x0, x1, block):  # this pass's block, as the mean of the passes so far
        options.observer(y0, y1, x0, x1, (state["total"][y0 - oy:y1 - oy, x0 - ox:x1 - ox] + block) / (done + 1))

    try:
        while not finished():
            result = render(prep, method_name, params,
                            dataclasses.replace(options, seed=pass_seed(options.seed, done),
                                    observer=observe if options.observer is not None else None),
                            executor, source)
            if result.variance is None:
                raise UserError(f"{source}: method {method_name} is deterministic; progressive options "
                                "(--passes, --time-budget, --target-error, --checkpoint) need a stochastic method "
                                "such as montecarlo")
            state["total"] += result.image  # in place, and the pass's arrays let go: the memory estimate
            state["var_total"] += result.variance  # (api.check_memory) counts three image-sized sums
            error_bounds.add_up(state["bound_total"], result.error_bound)
            for name, array in result.layers.items():
                layers[name] = layers[name] + array if name in layers else array
            layer_passes += 1
            result.image = result.variance = result.error_bound = None
            done += 1
            elapsed += result.seconds
            state["passes"], state["elapsed"] = np.array(done), np.array(elapsed)
            state["compile"] = np.array(max(float(state["compile"]), result.compile_seconds))
            if options.on_pass:
                options.on_pass(done, mean_relative_error(state["total"], state["var_total"], done))
            if checkpoint and time.perf_counter() - last_save >= options.checkpoint_interval:
                _save(checkpoint, state)
                last_save = time.perf_counter()
    except KeyboardInterrupt:
        if checkpoint and done:
            _save(checkpoint, state)
        raise
    if checkpoint:
        _save(checkpoint, state)
    image = state["total"] / done
    variance = state["var_total"] / done**2
    bound = np.zeros_like(state["bound_total"])
    error_bounds.add_up(bound, state.pop("bound_total"), done)
    stats = {"passes": done, "estimated mean relative error": mean_relative_error(state["total"], state["var_total"],
                                                                                   done)}
    if result is not None:
        stats.update(result.stats)
    stats.update(error_bounds.summary(bound))
    return RenderResult(image, method_name, result.params if result else params, elapsed, float(state["compile"]),
                        stats, variance, done, bound, {k: v / layer_passes for k, v in layers.items()})
