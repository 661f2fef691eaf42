"""What an import says about a file: notes grouped by kind, the warning for a scene without lights,
and every problem of a refused file at once (docs/formats/README.md).

Notes are Python warnings (category `ImportNote`), one line each; notes of one kind (the same text for
keys that differ only in their indices, e.g. `materials[3].doubleSided`) are one line with a count.
A refused file's problems are collected by `Problems` and raised as one UserError: one line, or
(`UserError.several`) a first line that counts them, then one line each.
"""
from __future__ import annotations

import contextlib
import re
import warnings

import numpy as np

from ..errors import UserError, counted

MAX_PROBLEMS = 20  # a refused file lists at most this many problems


class ImportNote(UserWarning):
    """What an importer approximates, converts or leaves out, one line each."""


def grouped(notes: list[tuple[str, str]]) -> list[str]:
    """(key, text) notes as lines `key: text`; those whose keys differ only in their indices and whose
    texts agree are one line: `materials[0, 1, 2, ...].doubleSided (16 materials): text`."""
    kinds: dict[tuple[str, str], list[str]] = {}
    for key, text in notes:
        keys = kinds.setdefault((re.sub(r"\[\d+\]", "[*]", key), text), [])
        if key not in keys:
            keys.append(key)
    return [f"{keys[0] if len(keys) == 1 else _merged(keys)}: {text}" for (_, text), keys in kinds.items()]


def _merged(keys: list[str]) -> str:
    """One key for keys that differ in their indices: the indices listed where only one differs."""
    parts = [re.split(r"\[(\d+)\]", k) for k in keys]  # names at even places, indices at odd
    varying = [i for i in range(1, len(parts[0]), 2) if len({p[i] for p in parts}) > 1]
    if len(varying) != 1:
        return re.sub(r"\[\d+\]", "[*]", keys[0]) + f" ({len(keys)} alike)"
    i = varying[0]
    out = list(parts[0])
    out[i] = ", ".join(p[i] for p in parts[:8]) + (", ..." if len(parts) > 8 else "")
    noun = (re.findall(r"\w+$", out[i - 1]) or ["entries"])[0]
    return "".join(t if j % 2 == 0 else f"[{t}]" for j, t in enumerate(out)) + f" ({len(keys)} {noun})"


def warn(lines, category=ImportNote):
    """Each line as a warning of `category`."""
    for line in lines:
        warnings.warn(line, category, stacklevel=3)


def _points(raw: dict) -> np.ndarray:
    """The points that bound the scene's shapes (vertices, centres with radii, box and quad corners)."""
    pts = []
    for shape in raw.get("shape", []):
        for key in ("vertices", "corners"):
            if key in shape:
                pts.append(np.asarray(shape[key], float).reshape(-1, 3))
        if "min" in shape and "max" in shape:
            pts.append(np.array([shape["min"], shape["max"]], float))
        if "center" in shape:
            c, r = np.asarray(shape["center"], float), float(shape.get("radius", 1.0))
            pts.append(np.array([c - r, c + r]))
    return np.concatenate(pts) if pts else np.zeros((0, 3))


def bounding_sphere(raw: dict) -> tuple[np.ndarray, float] | None:
    """(centre, radius) of the shapes' bounding box's circumscribed sphere, or None without shapes."""
    pts = _points(raw)
    if not len(pts):
        return None
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return (lo + hi) / 2.0, float(np.linalg.norm(hi - lo)) / 2.0


def default_camera(raw: dict, fov: float, height: int) -> dict:
    """A square perspective camera of vertical `fov` degrees framing the shapes' bounding sphere (the
    unit sphere without shapes), looking at its centre down -z from +z of it, +y up (a glTF's up)."""
    centre, radius = bounding_sphere(raw) or (np.zeros(3), 1.0)
    radius = radius if radius > 0.0 else 1.0
    distance = radius / np.sin(np.radians(fov) / 2.0)  # the sphere touches the edges of the view
    position = centre + [0.0, 0.0, distance]
    return {"type": "perspective", "position": position.tolist(), "look_at": centre.tolist(), "up": [0.0, 1.0, 0.0],
            "fov": fov, "width": height, "height": height}


def no_lights(raw: dict, source: str) -> str | None:
    """The warning for a scene without lights, with a point lamp to add by --set: above and behind
    the camera (never at it: the air-light of a point light at the camera diverges) by a quarter of
    the distance s to the scene's centre, so sqrt(1.25² + 0.25²) s = sqrt(1.625) s from a centre on the
    view axis: intensity 1.625 s² lights it with 1 W/m²; None when the scene has lights or emitting shapes."""
    if raw.get("light") or any(isinstance(s, dict) and "emission" in s for s in raw.get("shape", [])):
        return None
    cam = raw.get("camera")
    lamp = ""
    if isinstance(cam, dict) and {"position", "look_at"} <= set(cam):
        pos, at = np.asarray(cam["position"], float), np.asarray(cam["look_at"], float)
        up = np.asarray(cam.get("up", [0.0, 1.0, 0.0]), float)
        sphere = bounding_sphere(raw)
        scale = float(np.linalg.norm(sphere[0] - pos)) if sphere is not None else float(np.linalg.norm(at - pos))
        scale = scale if scale > 0.0 else 1.0
        forward = (at - pos) / np.linalg.norm(at - pos)
        up = up - (up @ forward) * forward
        up = up / np.linalg.norm(up) if np.linalg.norm(up) > 0 else up
        where = pos + 0.25 * scale * (up - forward)
        lamp = (f" add a lamp above and behind the camera with --set 'light=[{{type = \"point\", position = "
                f"[{', '.join(f'{x:.4g}' for x in where)}], intensity = {1.625 * scale * scale:.4g}}}]'"
                " (docs/formats/README.md)")
    return f"{source}: the scene has no lights; it renders black;" + (lamp or " add a light with --set 'light=[...]'")


def _location(message: str) -> tuple[str, int]:
    """(file, line) of a `file:line: ...` message; ("", 0) for others (glTF's keys), which keep their order."""
    m = re.match(r"(.+?):(\d+): ", message)
    return (m.group(1), int(m.group(2))) if m else ("", 0)


def every(problems: list[str]):
    """Raise the problems of one element: one line, or UserError.several; return when there are none."""
    if len(problems) == 1:
        raise UserError(problems[0])
    if problems:
        raise UserError.several(f"{counted(len(problems), 'problem')}, one a line with its fix", problems, MAX_PROBLEMS)


class Problems:
    """The problems of one file, collected so that a refused file names them all in one run.

    `each()` wraps the reading of one element: its UserError is recorded and reading goes on with the
    next element; `check()` raises them all (first the fatal one, if reading stopped at one)."""

    def __init__(self, source: str):
        self.source = source
        self.items: list[str] = []

    @contextlib.contextmanager
    def each(self):
        try:
            yield
        except UserError as exc:
            self.add(exc)

    def add(self, exc: UserError):
        """Record `exc`'s problem (or problems: `UserError.several`'s lines after the first)."""
        self.items += [line for line in (exc.lines[1:] if exc.lines else [str(exc)]) if line not in self.items]

    def check(self, fatal: UserError | None = None):
        """Raise the problems found (a fatal one first), or return when there are none."""
        items = sorted(self.items, key=_location)  # by file and line where messages give them (stable)
        if fatal is not None:
            first = fatal.lines[1:] if fatal.lines else [str(fatal)]
            items = [*first, *[i for i in items if i not in first]]
        if len(items) == 1:
            raise UserError(items[0])
        if items:
            stop = "; reading stopped at the first" if fatal is not None else ""
            raise UserError.several(f"{self.source}: {counted(len(items), 'problem')}, one a line with its fix{stop}",
                                    items, MAX_PROBLEMS)
