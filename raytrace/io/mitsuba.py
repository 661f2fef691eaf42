"""Mitsuba 3 XML scenes in and out (docs/formats/mitsuba.md).

`read_scene` reads the subset a fog scene uses into the scene dict: `<default>` / `$name`,
`<include>` and `<path>` (files looked up as mitsuba3's file resolver does), ids and `<ref>`,
transforms, the shapes obj, ply, rectangle, cube, sphere, disk and cylinder, the bsdfs diffuse,
twosided, null and dielectric, the emitters point, spot and directional, homogeneous media on the
sensor and inside shapes, the perspective sensor (or a pinhole thinlens) with its film and sampler.
Everything else is refused, one line naming the file, the line and the element for each element the
file holds that is not read (all of them in one run: report.Problems). The file is parsed
with defusedxml (no entity expansion); meshes are read with trimesh and travel inline.

`export` writes a scene for Mitsuba's `volpath` with max_depth = 2 (single scattering with shadowed
next-event estimation, as ours), the fog on the sensor, a box pixel filter, twosided diffuse bsdfs and
the meshes as binary PLY files beside the XML.
"""
from __future__ import annotations

import copy
import math
import os
import re
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..errors import UserError
from . import emitters
from .meshfile import read_mesh
from .report import ImportNote, Problems, every, warn

# Mitsuba's named indices of refraction (include/mitsuba/render/ior.h: Hecht, Optics, at ~589 nm)
IOR = {"vacuum": 1.0, "helium": 1.000036, "hydrogen": 1.000132, "air": 1.000277, "carbon dioxide": 1.00045,
       "water": 1.3330, "acetone": 1.36, "ethanol": 1.361, "carbon tetrachloride": 1.461, "glycerol": 1.4729,
       "benzene": 1.501, "silicone oil": 1.52045, "bromine": 1.661, "water ice": 1.31, "fused quartz": 1.458,
       "pyrex": 1.470, "acrylic glass": 1.49, "polypropylene": 1.49, "bk7": 1.5046, "sodium chloride": 1.544,
       "amber": 1.55, "pet": 1.5750, "diamond": 2.419}
PROPERTY_TAGS = {"float", "integer", "boolean", "string", "point", "vector", "rgb", "spectrum", "transform"}
OBJECT_TAGS = {"shape", "bsdf", "emitter", "medium", "phase", "sensor", "film", "sampler", "rfilter", "integrator",
               "texture", "volume"}
FACET_PIXELS = 0.25  # a tessellated sphere's facets span at most this many pixels seen from the camera
SEGMENTS = (64, 256)  # the clamp on a curved shape's segments (spheres, disks, cylinders)
INTERIOR_SEGMENTS = 64  # the mesh of a curved shape holding a medium (an exact sphere's rows) at most this fine


# ------------------------------------------------------------------------------------------- reading

COATED = ("plastic", "roughplastic")  # read as their diffuse base, with a note


class _Doc:
    """The parsed XML files: every element's file and line, ids, `$name` parameters, the include stack."""

    def __init__(self):
        self.where: dict = {}  # element -> (file, line)
        self.params: dict[str, str] = {}
        self.ids: dict[str, ET.Element] = {}
        self.stack: list[Path] = []
        self.folders: list[Path] = []  # Mitsuba's FileResolver: the folders a relative file name is looked up in

    def resolve(self, name: str) -> Path | None:
        """The first of `folders` that holds `name` (mitsuba3 src/core/fresolver.cpp `resolve`), or None."""
        if Path(name).is_absolute():
            return Path(name) if Path(name).exists() else None
        return next((folder / name for folder in self.folders if (folder / name).exists()), None)

    def searched(self) -> str:
        return ", ".join(str(f) for f in dict.fromkeys(self.folders))

    def message(self, el, problem: str, fix: str) -> str:
        file, line = self.where.get(el, ("?", 0))
        return f"{file}:{line}: {_describe(el)}: {problem}; {fix}"

    def fail(self, el, problem: str, fix: str):
        raise UserError(self.message(el, problem, fix))

    def parse(self, path: Path) -> ET.Element:
        """The root element of `path`, every element's line recorded; malformed XML and entity
        declarations are refused with their line."""
        from defusedxml import DTDForbidden, EntitiesForbidden, ExternalReferenceForbidden
        from defusedxml.ElementTree import DefusedXMLParser

        doc = self

        class Builder(ET.TreeBuilder):
            def start(self, tag, attrs):
                el = super().start(tag, attrs)
                doc.where[el] = (str(path), parser.parser.CurrentLineNumber)
                return el

        parser = DefusedXMLParser(target=Builder())
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise UserError(f"{path}: cannot read the scene file ({exc.strerror}); check the path and its "
                            "permissions") from None
        try:
            parser.feed(data)
            return parser.close()
        except ET.ParseError as exc:
            line, col = exc.position
            raise UserError(f"{path}:{line}: malformed XML at column {col} ({str(exc).split(':')[0]}); fix the "
                            "syntax at that line") from None
        except (EntitiesForbidden, DTDForbidden, ExternalReferenceForbidden) as exc:
            raise UserError(f"{path}:{parser.parser.CurrentLineNumber}: XML entity declarations are refused "
                            f"({type(exc).__name__}: entity expansion can exhaust memory); remove the <!DOCTYPE> "
                            "and <!ENTITY> declarations") from None

    def load(self, path: Path) -> list[ET.Element]:
        """The scene's top-level elements with includes spliced in and `$name` substituted."""
        path = path.resolve()
        if not self.stack:  # mitsuba3 src/core/python/parser.cpp load_file: the main file's folder first
            self.folders = [path.parent]
        if path in self.stack:
            chain = " -> ".join(p.name for p in [*self.stack, path])
            raise UserError(f"{self.stack[-1]}: <include> loop ({chain}); remove the include that closes the loop")
        self.stack.append(path)
        root = self.parse(path)
        if root.tag != "scene":
            self.fail(root, "the root element must be <scene>", 'write <scene version="3.0.0"> ... </scene>')
        self._substitute(root)
        children = self._expand(root, path, top=True)
        self.stack.pop()
        return children

    def _expand(self, el, path, top=False) -> list[ET.Element]:
        out = []
        for child in list(el):
            self._substitute(child)
            if child.tag == "default":
                name, value = child.get("name"), child.get("value")
                if not name or value is None:
                    self.fail(child, "needs name and value", '<default name="x" value="1.0"/>')
                self.params.setdefault(name, value)  # the first definition wins, as in Mitsuba
            elif child.tag == "include":
                name = child.get("filename")
                if not name:
                    self.fail(child, "needs a filename", '<include filename="other.xml"/>')
                # parser.cpp TagType::Include: the including file's folder, then the resolver's folders
                outer = self.folders
                self.folders = [path.parent, *outer]
                target = self.resolve(name)
                if target is None or not target.is_file():
                    self.fail(child, f"included file {name!r} not found in {self.searched()}", "fix the filename "
                              "(relative to the including file, the main file or a <path>)")
                out += self.load(target)
                self.folders = outer
            elif child.tag == "path":
                self.add_folder(child, path, top)
            else:
                child[:] = self._expand(child, path)
                out.append(child)
        return out

    def add_folder(self, el, path, top):
        """<path value="..."/>: a folder searched first from now on (parser.cpp TagType::Resource: relative
        to the file's folder, else through the resolver)."""
        if not top:
            self.fail(el, "<path> can only be a child of <scene>", "move it to the top level of the file")
        value = el.get("value")
        if not value:
            self.fail(el, "needs a value", '<path value="meshes"/>')
        folder = path.parent / value
        if not folder.exists():
            folder = self.resolve(value)
        if folder is None or not folder.is_dir():
            self.fail(el, f"folder {value!r} not found (relative to {path.parent} or in {self.searched()})",
                      "fix the folder name")
        self.folders.insert(0, folder)

    def _substitute(self, el):
        for key, value in el.attrib.items():
            if "$" not in value:
                continue
            for name in sorted(self.params, key=len, reverse=True):  # longest first, as Mitsuba
                value = re.sub(r"(?<!\\)\$" + re.escape(name), lambda m: self.params[name], value)
            left = re.search(r"(?<!\\)\$(\w+)", value)
            if left:
                self.fail(el, f"parameter ${left.group(1)} in {key}={el.attrib[key]!r} has no value",
                          f'add <default name="{left.group(1)}" value="..."/> to the scene')
            el.attrib[key] = value

    def collect_ids(self, elements):
        for el in elements:
            for sub in el.iter():
                if sub.get("id") and sub.tag != "ref":
                    if sub.get("id") in self.ids:
                        self.fail(sub, f"duplicate id {sub.get('id')!r}", "give every object its own id")
                    self.ids[sub.get("id")] = sub

    def deref(self, el):
        """The object a <ref id=.../> points at (or el itself)."""
        if el.tag != "ref":
            return el
        target = self.ids.get(el.get("id", ""))
        if target is None:
            self.fail(el, f"no object has id {el.get('id')!r}", "declare it before referencing it, or fix the id")
        return target


def _describe(el) -> str:
    attrs = " ".join(f'{k}="{el.get(k)}"' for k in ("type", "name", "id") if el.get(k))
    return f"<{el.tag}{' ' + attrs if attrs else ''}>"


class _Props:
    """The parameters of one plugin element: named values and nested objects, each used at most once;
    what is left unread is refused (Mitsuba refuses unreferenced parameters too)."""

    def __init__(self, doc: _Doc, el):
        self.doc, self.el = doc, el
        self.values: dict[str, ET.Element] = {}
        self.objects: list[tuple[str, ET.Element]] = []  # (name, element after <ref>) in order
        for child in el:
            if child.tag in PROPERTY_TAGS:
                name = child.get("name")
                if not name:
                    doc.fail(child, "has no name", f'add name="..." to the <{child.tag}>')
                self.values[name] = child
            elif child.tag in OBJECT_TAGS or child.tag == "ref":
                self.objects.append((child.get("name", ""), doc.deref(child)))
            else:
                doc.fail(child, f"unsupported element inside {_describe(el)}", "remove it (docs/formats/mitsuba.md "
                         "lists what is read)")
        self.read: set[str] = set()

    def number(self, name, default=None, kinds=("float", "integer")):
        child = self.values.get(name)
        if child is None:
            return default
        self.read.add(name)
        if child.tag not in kinds:
            self.doc.fail(child, f"expected <{kinds[0]}>", f'write <{kinds[0]} name="{name}" value="..."/>')
        return _finite(self.doc, child, child.get("value", ""), integer=child.tag == "integer")

    def string(self, name, default=None):
        child = self.values.get(name)
        if child is None:
            return default
        self.read.add(name)
        if child.tag != "string":
            self.doc.fail(child, "expected <string>", f'write <string name="{name}" value="..."/>')
        return child.get("value", "")

    def boolean(self, name, default=False):
        child = self.values.get(name)
        if child is None:
            return default
        self.read.add(name)
        value = child.get("value", "").lower()
        if child.tag != "boolean" or value not in ("true", "false"):
            self.doc.fail(child, "expected <boolean> true or false", f'write <boolean name="{name}" value="true"/>')
        return value == "true"

    def point(self, name, default=None):
        child = self.values.get(name)
        if child is None:
            return None if default is None else np.asarray(default, float)
        self.read.add(name)
        if child.tag not in ("point", "vector"):
            self.doc.fail(child, "expected <point> or <vector>", f'write <point name="{name}" value="x, y, z"/>')
        return _xyz(self.doc, child, 0.0)

    def colour(self, name, default=None, kind="reflectance"):
        """An rgb, a float or a spectrum as three numbers; textures are refused. A spectrum sampled at
        wavelengths goes to sRGB as Mitsuba's RGB variants take it (io/spectra.py): `kind` "emission"
        without D65 and clamped to >= 0, "reflectance" with D65 and into [0, 1], "medium" with D65, >= 0.
        A one-number spectrum is grey, but an emitter's is that value over the CIE range, as Mitsuba's
        RGB variants read it: v (1.2048, 0.9483, 0.9092), the equal-energy white in sRGB."""
        child = self.values.get(name)
        if child is None:
            for oname, obj in self.objects:
                if oname == name:
                    self.doc.fail(obj, f"textured {name} ({_describe(obj)}) is not supported",
                                  f'give {name} a constant: <rgb name="{name}" value="r, g, b"/>')
            return None if default is None else np.full(3, float(default))
        self.read.add(name)
        text = child.get("value", "")
        if child.tag == "spectrum" and ":" in text:
            from .spectra import to_srgb

            return to_srgb(*_samples(self.doc, child, text), kind == "emission", kind == "reflectance")
        if child.tag not in ("rgb", "float", "spectrum"):
            self.doc.fail(child, "expected <rgb>, <float> or <spectrum>", f'write <rgb name="{name}" value="r, g, b"/>')
        values = [_finite(self.doc, child, t) for t in _tokens(text)]
        if len(values) not in (1, 3):
            self.doc.fail(child, f"expected one or three numbers, got {len(values)}", 'write value="r, g, b"')
        if child.tag == "spectrum" and len(values) == 1 and kind == "emission":  # a flat spectrum, not grey
            from .spectra import CIE_RANGE, to_srgb

            return to_srgb(np.array(CIE_RANGE), np.array(values * 2), True, False)
        return np.array(values * 3 if len(values) == 1 else values, float)

    def transform(self, name="to_world"):
        child = self.values.get(name)
        if child is None:
            return np.eye(4)
        self.read.add(name)
        if child.tag != "transform":
            self.doc.fail(child, "expected <transform>", f'write <transform name="{name}"> ... </transform>')
        return _transform(self.doc, child)

    def nested(self, tag, name=None):
        """The nested objects of this tag (and name, when given)."""
        return [obj for oname, obj in self.objects if obj.tag == tag and (name is None or oname == name)]

    def done(self, ignored=()):
        """Refuse parameters nobody read, all of them at once (`ignored`: accepted and documented as
        having no effect here)."""
        every([self.doc.message(child, f"parameter {name!r} of {_describe(self.el)} is not read",
                                "remove it (docs/formats/mitsuba.md lists what is read)")
               for name, child in self.values.items() if name not in self.read and name not in ignored])


def _tokens(text: str) -> list[str]:
    return [t for t in re.split(r"[,\s]+", text.strip()) if t]


def _samples(doc, el, text) -> tuple[np.ndarray, np.ndarray]:
    """(wavelengths, values) of a spectrum's "w:v, w:v, ..." with at least two increasing wavelengths
    (mitsuba3 src/core/properties.cpp `Spectrum`)."""
    fix = 'write value="400:0.5, 500:0.6, ..." (wavelengths in nm, increasing)'
    tokens = _tokens(text)
    pairs = [t.split(":") for t in tokens]
    for t, pair in zip(tokens, pairs):
        if len(pair) != 2:
            doc.fail(el, f"{t!r} is not a wavelength:value pair", fix)
    w, v = (np.array([_finite(doc, el, p[i]) for p in pairs]) for i in (0, 1))
    if len(w) < 2 or np.any(np.diff(w) <= 0):
        doc.fail(el, "a sampled spectrum needs two or more wavelengths in increasing order", fix)
    return w, v


def _finite(doc, el, text, integer=False):
    try:
        value = int(text) if integer else float(text)
    except ValueError:
        doc.fail(el, f"{text!r} is not a{'n integer' if integer else ' number'}", "write a number such as 1.0")
    if not math.isfinite(value):
        doc.fail(el, f"{text!r} is not finite", "use a finite number")
    return value


def _xyz(doc, el, default):
    if el.get("value") is not None:
        values = [_finite(doc, el, t) for t in _tokens(el.get("value"))]
        if len(values) not in (1, 3):
            doc.fail(el, f"expected one or three numbers, got {len(values)}", 'write value="x, y, z"')
        return np.array(values * 3 if len(values) == 1 else values, float)
    return np.array([_finite(doc, el, el.get(k)) if el.get(k) is not None else default for k in "xyz"], float)


def _rotation(axis, degrees):
    """Rotation by `degrees` about `axis`, counter-clockwise looking down the axis: Rodrigues'
    c I + (1 - c) u u^T + s [u]x with the axis as given, unnormalised, as Mitsuba builds it (so a
    non-unit axis also scales, in Mitsuba and here)."""
    u = np.asarray(axis, float)
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    t = math.radians(degrees)
    R = np.eye(4)
    R[:3, :3] = math.cos(t) * np.eye(3) + (1.0 - math.cos(t)) * np.outer(u, u) + math.sin(t) * K
    return R


def _look_at(origin, target, up):
    """Mitsuba's look_at: columns left = up x dir, up' = dir x left, dir, origin."""
    d = target - origin
    d = d / np.linalg.norm(d)
    left = np.cross(up, d)
    left = left / np.linalg.norm(left)
    M = np.eye(4)
    M[:3, 0], M[:3, 1], M[:3, 2], M[:3, 3] = left, np.cross(d, left), d, origin
    return M


def _transform(doc, el) -> np.ndarray:
    """A <transform>'s 4x4 matrix: each operation is applied after the ones before it."""
    M = np.eye(4)
    for op in el:
        if op.tag == "translate":
            T = np.eye(4)
            T[:3, 3] = _xyz(doc, op, 0.0)
        elif op.tag == "scale":
            T = np.diag([*_xyz(doc, op, 1.0), 1.0])
        elif op.tag == "rotate":
            axis = _xyz(doc, op, 0.0)
            if not np.any(axis):
                doc.fail(op, "the rotation axis is zero", 'write <rotate x="0" y="1" z="0" angle="30"/>')
            T = _rotation(axis, _finite(doc, op, op.get("angle", "")))
        elif op.tag == "matrix":
            values = [_finite(doc, op, t) for t in _tokens(op.get("value", ""))]
            if len(values) not in (9, 16):
                doc.fail(op, f"expected 9 or 16 numbers (row by row), got {len(values)}", "give a 4x4 matrix")
            T = np.eye(4)
            n = 4 if len(values) == 16 else 3
            T[:n, :n] = np.reshape(values, (n, n))
        elif op.tag == "lookat":
            origin, target = (np.array([_finite(doc, op, t) for t in _tokens(op.get(k, ""))]) for k in ("origin", "target"))
            up = np.array([_finite(doc, op, t) for t in _tokens(op.get("up", "0 0 0"))])
            if len(origin) == 3 and len(target) == 3 and len(up) == 3 and not np.any(up) and np.any(target - origin):
                up = emitters.perpendicular((target - origin) / np.linalg.norm(target - origin))
            if len(origin) != 3 or len(target) != 3 or len(up) != 3:
                doc.fail(op, "origin, target and up need three numbers each", 'write origin="x, y, z"')
            d = target - origin
            if not np.linalg.norm(d) > 0 or not np.linalg.norm(np.cross(up, d)) > 1e-12 * np.linalg.norm(d) * max(
                    np.linalg.norm(up), 1e-300):
                doc.fail(op, "target equals origin, or up is zero or parallel to the view direction",
                         "give a target away from the origin and an up not along target - origin")
            T = _look_at(origin, target, up)
        else:
            doc.fail(op, "unsupported inside <transform>", "use translate, rotate, scale, matrix or lookat")
        M = T @ M
    if not np.all(np.isfinite(M)) or abs(np.linalg.det(M[:3, :3])) == 0.0 or np.any(M[3] != [0, 0, 0, 1]):
        doc.fail(el, "is singular, overflows or is not affine", "use an invertible affine transform")
    return M


def _apply(M, points):
    return np.asarray(points, float) @ M[:3, :3].T + M[:3, 3]


def _similarity(M):
    """(uniform scale, True) when M's linear part is a rotation times a uniform scale."""
    L = M[:3, :3]
    s = abs(np.linalg.det(L)) ** (1.0 / 3.0)
    return s, bool(np.allclose(L.T @ L, s * s * np.eye(3), rtol=0, atol=1e-9 * s * s))


class MitsubaNote(ImportNote):
    """What the Mitsuba reader approximates, one line each (docs/formats/mitsuba.md)."""


class _Reader:
    def __init__(self, path: Path, problems: Problems):
        self.path, self.problems = path, problems
        self.notes: list[str] = []  # what is read approximately (`read_scene` warns)
        self.doc = _Doc()
        self.top = self.doc.load(path)
        self.doc.collect_ids(self.top)
        self.fog = None  # the sensor's medium element
        self.lights: list[dict] = []  # in the file's order (rectangles, disks and spheres with an area emitter too)

    def scene(self) -> dict:
        """The scene dict; each element that cannot be read is recorded in `problems` and left out."""
        doc, each = self.doc, self.problems.each
        sensors = [el for el in self.top if el.tag == "sensor"]
        # a stand-in while the sensor is refused: shapes are still read for their own problems
        self.cam = {"position": [0.0, 0.0, 0.0], "fov": 45.0, "height": 512}
        out = {"name": self.path.stem}
        with each():
            if len(sensors) != 1:
                raise UserError(f"{self.path}: <sensor>: the scene has {len(sensors)} sensors; keep exactly one "
                                "perspective sensor")
            out["camera"] = self.cam = self.camera(sensors[0])
        if self.fog is not None:
            with each():
                out["medium"] = self.medium(self.fog)
        shapes, lights = [], self.lights
        for el in self.top:
            with each():
                if el.tag == "shape":
                    shape = self.shape(el)
                    if shape is not None:
                        shapes.append(shape)
                elif el.tag == "emitter":
                    if not (el.get("type") == "area" and el.get("id")):  # (else a shape's by <ref>: read there)
                        lights.append(self.emitter(el))
                elif el.tag not in ("sensor", "bsdf", "medium", "texture", "phase", "integrator"):
                    # objects declared for <ref> are read where referenced; the integrator: ours is single scattering
                    doc.fail(el, "is not read", "remove it (docs/formats/mitsuba.md lists what is read)")
        if shapes:
            out["shape"] = shapes
        if lights:
            out["light"] = lights
        out["render"] = {"volumetric_shadows": True}  # Mitsuba's volpath shadows the medium
        return out

    # ---------------------------------------------------------------------------------- sensor

    def camera(self, el) -> dict:
        doc = self.doc
        if el.get("type") not in ("perspective", "thinlens"):
            doc.fail(el, "only the perspective sensor (and thinlens with aperture_radius 0) is read",
                     'use <sensor type="perspective">')
        p = _Props(doc, el)
        if el.get("type") == "thinlens" and p.number("aperture_radius", math.nan) != 0.0:
            doc.fail(p.values.get("aperture_radius", el), "a thinlens sensor's aperture_radius > 0 (depth of field) "
                     "is not read", 'use <sensor type="perspective"> (a pinhole) or aperture_radius 0')
        films = p.nested("film")
        W, H = 768, 576
        if films:
            film = films[0]
            if film.get("type") != "hdrfilm":
                doc.fail(film, "only hdrfilm is read", 'use <film type="hdrfilm">')
            f = _Props(doc, film)
            W, H = f.number("width", W, ("integer",)), f.number("height", H, ("integer",))
            if W <= 0 or H <= 0:
                doc.fail(film, "width and height must be positive", "give the image size in pixels")
            for k in ("crop_offset_x", "crop_offset_y", "crop_width", "crop_height"):
                if k in f.values:
                    doc.fail(f.values[k], "crop windows are not read", "remove the crop (render.py render --crop "
                             "does the same)")
            for r in f.nested("rfilter"):  # ours averages the pixel (a box) with spp > 1
                _Props(doc, r).done(ignored=("radius", "stddev", "B", "C", "lobes"))
            f.done(ignored=("pixel_format", "component_format", "file_format", "sample_border", "banner",
                            "compensate", "high_quality_edges"))
        spp = 4
        for s in p.nested("sampler"):
            q = _Props(doc, s)
            spp = q.number("sample_count", 4, ("integer",))
            if spp <= 0:
                doc.fail(s, "sample_count must be positive", "give the samples per pixel")
            q.done(ignored=("seed", "jitter", "scramble_seed", "pixel_samples"))
        aspect = W / H
        if "fov" in p.values and "focal_length" in p.values:
            doc.fail(el, "gives both fov and focal_length", "keep one")
        if "fov" in p.values:
            fov = p.number("fov")
            axis = (p.string("fov_axis", "x") or "").lower()
            if axis == "smaller":
                axis = "y" if aspect > 1 else "x"
            elif axis == "larger":
                axis = "x" if aspect > 1 else "y"
        else:
            text = p.string("focal_length", "50mm")
            try:
                f = float(text.removesuffix("mm"))
            except ValueError:
                doc.fail(p.values["focal_length"], f"{text!r} is not a focal length", 'write value="35mm"')
            fov, axis = 2.0 * math.degrees(math.atan(math.hypot(36.0, 24.0) / (2.0 * f))), "diagonal"
        if axis not in ("x", "y", "diagonal") or not 0.0 < fov < 180.0:
            doc.fail(el, f"fov {fov:g} along {axis!r}", "give 0 < fov < 180 and fov_axis x, y, diagonal, smaller "
                     "or larger")
        t = math.tan(math.radians(fov) / 2.0)
        tan_y = {"x": t / aspect, "y": t, "diagonal": t / math.sqrt(1.0 + aspect * aspect)}[axis]
        M = p.transform()
        left, up, fwd, pos = (M[:3, i] for i in range(4))
        n = [np.linalg.norm(v) for v in (left, up, fwd)]
        if not np.allclose(n, n[0], rtol=1e-6) or abs(left @ up) + abs(up @ fwd) + abs(fwd @ left) > 1e-6 * n[0] ** 2:
            doc.fail(p.values["to_world"], "the sensor's to_world scales or shears", "use a lookat, rotations and "
                     "translations")
        if np.cross(fwd, up) @ left > 0:
            doc.fail(p.values["to_world"], "mirrors the image (a negative scale)", "remove the mirroring scale")
        media = p.nested("medium")
        if len(media) > 1:
            doc.fail(el, "has more than one medium", "give the sensor one homogeneous medium")
        self.fog = media[0] if media else None
        for k in ("principal_point_offset_x", "principal_point_offset_y"):
            if p.number(k, 0.0):
                doc.fail(p.values[k], "an off-centre principal point is not read", f"remove {k}")
        # focus_distance: every projective camera reads it (src/render/sensor.cpp ProjectiveCamera); no effect
        # without a lens (a thinlens of aperture_radius 0 is a pinhole: thinlens.cpp sets it to epsilon)
        p.done(ignored=("near_clip", "far_clip", "shutter_open", "shutter_close", "focus_distance"))
        fwd, up = fwd / n[2], up / n[1]
        return {"type": "perspective", "position": pos.tolist(), "look_at": (pos + fwd).tolist(), "up": up.tolist(),
                "fov": math.degrees(2.0 * math.atan(tan_y)), "width": W, "height": H, "spp": spp}

    # ---------------------------------------------------------------------------------- media

    def medium(self, el) -> dict:
        doc = self.doc
        if el.get("type") != "homogeneous":
            doc.fail(el, "only homogeneous media are read", 'use <medium type="homogeneous">')
        p = _Props(doc, el)
        for name in ("sigma_t", "albedo"):
            for v in p.nested("volume", name):
                if v.get("type") != "constvolume":
                    doc.fail(v, f"a spatially varying {name} is not read", f"give {name} a constant")
                q = _Props(doc, v)
                if "value" not in q.values:
                    doc.fail(v, "a constvolume needs its value", 'add <rgb name="value" value="..."/>')
                p.values[name] = q.values["value"]
                q.read.add("value")
                q.done()
        sigma_t = p.colour("sigma_t", 1.0, "medium") * p.number("scale", 1.0)
        albedo = p.colour("albedo", 0.75, "medium")
        if np.any(sigma_t < 0) or np.any(albedo < 0) or np.any(albedo > 1):
            doc.fail(el, "sigma_t must be >= 0 and albedo in [0, 1]", "fix the coefficients")
        phases = p.nested("phase")
        phase = "isotropic"
        if phases:
            ph = phases[0]
            q = _Props(doc, ph)
            if ph.get("type") == "hg":
                phase = {"type": "hg", "g": q.number("g", 0.8)}
            elif ph.get("type") in ("isotropic", "rayleigh"):
                phase = ph.get("type")
            else:
                doc.fail(ph, "only the isotropic, hg and rayleigh phase functions are read", 'use <phase type="hg">')
            q.done()
        p.done(ignored=("sample_emitters", "has_spectral_extinction"))
        return {"sigma_a": _channels(sigma_t * (1.0 - albedo)), "sigma_s": _channels(sigma_t * albedo), "phase": phase}

    # ---------------------------------------------------------------------------------- emitters

    def emitter(self, el) -> dict:
        doc = self.doc
        kind = el.get("type")
        if kind in ("constant", "envmap"):
            return self.environment(el, kind)
        if kind not in ("point", "spot", "directional"):
            doc.fail(el, f"{kind} emitters are not read", "use point, spot, directional, constant, envmap or an area "
                     "emitter inside a shape")
        p = _Props(doc, el)
        self.same_fog(p, el, "medium")
        if kind == "directional":
            M = p.transform()
            d = p.point("direction")
            d = M[:3, 2] if d is None else d
            if "direction" in p.values and "to_world" in p.values:
                doc.fail(el, "gives both direction and to_world", "keep one")
            if not np.linalg.norm(d) > 0:
                doc.fail(el, "the direction is zero", "give the direction the light travels")
            light = {"type": "directional", "direction": (d / np.linalg.norm(d)).tolist(),
                     "irradiance": _channels(p.colour("irradiance", 1.0, "emission"))}
            p.done()
            return light
        if "position" in p.values and "to_world" in p.values:
            doc.fail(el, "gives both position and to_world", "keep one")
        M = p.transform()
        pos = p.point("position")
        pos = M[:3, 3] if pos is None else pos
        light = {"type": kind, "position": pos.tolist(), "intensity": _channels(p.colour("intensity", 1.0, "emission"))}
        if kind == "spot":
            cutoff = p.number("cutoff_angle", 20.0)
            beam = p.number("beam_width", cutoff * 0.75)
            if not 0.0 < cutoff < 180.0 or beam < 0.0:
                doc.fail(el, f"cutoff_angle {cutoff:g}, beam_width {beam:g}", "give 0 < cutoff_angle < 180 and "
                         "beam_width >= 0 degrees")
            # Mitsuba: full intensity within beam_width, linear in the angle to zero at cutoff_angle
            axis = M[:3, 2] / np.linalg.norm(M[:3, 2])
            light.update(direction=axis.tolist(), cone_angle=cutoff, falloff_start=min(beam, cutoff),
                         falloff="mitsuba")
        p.done()
        return light

    def environment(self, el, kind) -> dict:
        """A constant emitter's radiance, or an envmap: equirectangular with Mitsuba's own interpolation
        (filter "mitsuba": mitsuba3 src/emitters/envmap.cpp, bilinear, columns at the texel centres, the
        first and last rows on the poles) looked up at u = atan2(x, -z) / 2 pi, v = acos(y) / pi in its
        to_world frame: u = 0 along -z, where ours has the map's centre column (our u = 1/2): its frame
        turned half a turn about y."""
        doc, p = self.doc, _Props(self.doc, el)
        self.same_fog(p, el, "medium")
        if kind == "constant":
            light = {"type": "environment", "radiance": _channels(p.colour("radiance", 1.0, "emission"))}
            p.done()
            return light
        name = p.string("filename")
        if not name:
            doc.fail(el, "an envmap without a filename (a bitmap given from Python) is not read",
                     '<string name="filename" value="sky.exr"/>')
        file = doc.resolve(name)
        if file is None or not file.is_file():
            doc.fail(p.values["filename"], f"envmap file {name!r} not found in {doc.searched()}",
                     "fix the filename (relative to the main file or a <path>)")
        if file.suffix.lower() != ".exr":
            doc.fail(p.values["filename"], f"envmap {file.name}: only OpenEXR maps are read (linear RGB, "
                     "equirectangular)", "convert it to .exr")
        scale = p.number("scale", 1.0)
        M = p.transform()
        L = M[:3, :3]
        if not np.allclose(L.T @ L, np.eye(3), rtol=0, atol=1e-9):
            doc.fail(p.values.get("to_world", el), "an envmap's to_world must be a rotation or a mirror (no scale "
                     "or shear)", "keep the rotation alone")
        from ..lights import environment

        p.done(ignored=("mis_compensation",))  # (sampling only)
        return {"type": "environment", "map": str(file), "scale": scale, "filter": "mitsuba",
                **environment.rotate_keys(L @ np.diag([-1.0, 1.0, -1.0]))}  # Mitsuba's frame x ours turned about y

    def same_fog(self, p, el, name):
        """A nested medium must be the sensor's (ours has one medium filling space)."""
        for m in p.nested("medium", name):
            if m is not self.fog:
                self.doc.fail(el, f"its {name} medium differs from the sensor's", "use the sensor's medium "
                              "(one medium fills space; closed shapes hold their own interior)")

    # ---------------------------------------------------------------------------------- shapes

    def shape(self, el) -> dict | None:
        doc = self.doc
        kind = el.get("type")
        if kind not in ("obj", "ply", "rectangle", "cube", "sphere", "disk", "cylinder"):
            doc.fail(el, f"{kind} shapes are not read", "use obj, ply, rectangle, cube, sphere, disk or cylinder")
        p = _Props(doc, el)
        radiance = None
        if p.nested("emitter"):  # (a refused emitter is listed, and the shape read on for its other problems)
            with self.problems.each():
                radiance = self.area(p.nested("emitter"), el)
        self.same_fog(p, el, "exterior")
        interiors = p.nested("medium", "interior")
        bsdfs = p.nested("bsdf")
        reflectance, interior = self.bsdf(bsdfs[0] if bsdfs else None, el)
        if interiors:
            if reflectance is not None:
                doc.fail(el, "a diffuse shape's interior is never reached (the surface is opaque)",
                         'give it <bsdf type="null"/> (index-matched) or "dielectric", or remove the interior')
            interior = {**self.medium(interiors[0]), **(interior or {})}
        elif interior is not None and interior.get("ior", 1.0) == 1.0 and radiance is None:
            p.done(ignored=("filename", "face_normals", "flip_normals", "flip_tex_coords", "center", "radius", "p0",
                            "p1", "to_world"))
            return None  # a null bsdf and no interior: invisible in Mitsuba
        elif interior is not None:
            interior = {"sigma_a": 0.0, "sigma_s": 0.0, **interior}  # clear glass
        if radiance is not None and interior is not None:
            doc.fail(el, "an emitter that holds a medium or refracts is not read", "give the emitting shape a "
                     "diffuse bsdf, or put the medium in a shape of its own")
        flip = p.boolean("flip_normals", False)
        if radiance is not None and kind in ("rectangle", "disk", "sphere"):
            light = self.area_light(el, p, kind, flip)
            light["radiance"] = radiance
            p.done(ignored=("flip_tex_coords",))
            self.lights.append(light)  # it occludes like the shape (its reflectance: not read)
            return None
        if radiance is not None and kind not in ("obj", "ply", "cube"):
            doc.fail(el, f"an emitting {kind} is not read", "use a rectangle, disk, sphere, cube, obj or ply shape")
        out = self.geometry(el, p, kind, interior is not None)
        if radiance is not None:  # emitting towards Mitsuba's shading normal (area.cpp: cos_theta(si.wi) > 0)
            if "faces" in out:  # (a box primitive's triangles face outward, as Mitsuba's cube)
                faces = emitters.oriented(out["faces"], out["vertices"], out["normals"]) if "normals" in out else \
                    np.asarray(out["faces"])
                out["faces"] = (faces[:, ::-1] if flip else faces).tolist()
            elif flip:
                doc.fail(p.values["flip_normals"], "a cube emitting inward is not read", "remove flip_normals")
            out["emission"] = radiance
        if reflectance is not None:
            out["reflectance"] = reflectance
        if interior is not None:
            out["interior"] = interior
        p.done(ignored=("face_normals", "flip_tex_coords"))
        return out

    def area(self, nested, shape) -> float | list[float]:
        """The radiance of a shape's area emitter (mitsuba3 src/emitters/area.cpp: `radiance`, default 1)."""
        doc = self.doc
        if len(nested) > 1:
            doc.fail(shape, "has more than one emitter", "keep one area emitter")
        el = nested[0]
        if el.get("type") != "area":
            doc.fail(el, f"a {el.get('type')} emitter inside a shape is not read", 'use <emitter type="area">')
        q = _Props(doc, el)
        self.same_fog(q, el, "medium")
        radiance = _channels(q.colour("radiance", 1.0, "emission"))
        q.done()
        return radiance

    def area_light(self, el, p, kind, flip) -> dict:
        """A rectangle, disk or sphere with an area emitter as our quad, disk or sphere light: Mitsuba's
        rectangle spans [-1, 1]^2 at z = 0 and a disk the unit disk there, both emitting towards their normal
        to_world^-T (0, 0, 1) (flip_normals: the other side); a sphere emits outward."""
        M = p.transform()
        n = np.linalg.inv(M[:3, :3]).T @ [0.0, 0.0, 1.0]
        n = (-1.0 if flip else 1.0) * n / np.linalg.norm(n)
        if kind == "rectangle":
            c = _apply(M, [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
            if np.cross(c[1] - c[0], c[3] - c[0]) @ n < 0.0:
                c = c[[0, 3, 2, 1]]  # wound towards the emitting side
            return {"type": "quad", "corners": c.tolist()}
        if kind == "disk":
            x, y = M[:3, 0], M[:3, 1]
            if not math.isclose(x @ x, y @ y, rel_tol=1e-9) or abs(x @ y) > 1e-9 * (x @ x):
                self.doc.fail(el, "an emitting disk's to_world stretches it into an ellipse", "scale it uniformly "
                              "in its plane, or use a mesh")
            return {"type": "disk", "center": M[:3, 3].tolist(), "normal": n.tolist(), "radius": float(np.linalg.norm(x))}
        if flip:
            self.doc.fail(p.values["flip_normals"], "a sphere emitting inward is not read", "remove flip_normals")
        sphere = self.geometry(el, p, kind, False)
        return {"type": "sphere", "center": sphere["center"], "radius": sphere["radius"]}

    def geometry(self, el, p, kind, holds_medium) -> dict:
        M = p.transform()
        if kind in ("obj", "ply"):
            return self.triangles(el, p, M)
        if kind == "rectangle":
            return {"primitive": "quad", "corners": _apply(M, [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]).tolist()}
        if kind == "cube":
            L = M[:3, :3]
            if np.count_nonzero(L - np.diag(np.diag(L))) == 0:
                lo, hi = _apply(M, [-1, -1, -1]), _apply(M, [1, 1, 1])
                return {"primitive": "box", "min": np.minimum(lo, hi).tolist(), "max": np.maximum(lo, hi).tolist()}
            from ..scene.meshes import box_triangles

            out = _soup(box_triangles(-np.ones(3), np.ones(3)), M)  # wound outward (a mirroring M: turned back)
            out["faces"] = np.asarray(out["faces"])[:, ::-1 if np.linalg.det(L) < 0 else 1].tolist()
            return out
        if kind == "sphere":
            c = M @ np.array([*p.point("center", [0.0, 0.0, 0.0]), 1.0])
            r = p.number("radius", 1.0)
            s, similar = _similarity(M)
            if not similar or not r > 0:
                self.doc.fail(el, "a sphere needs a positive radius and a to_world without non-uniform scale or "
                              "shear (Mitsuba's rule)", "scale it uniformly, or use a mesh for an ellipsoid")
            radius = float(r * s)
            return {"primitive": "sphere", "center": c[:3].tolist(), "radius": radius,
                    "segments": self.segments(c[:3], radius, holds_medium), "exact": True}
        from ..scene.meshes import cylinder_triangles

        n = self.segments(M[:3, 3], max(np.linalg.norm(M[:3, :2], axis=0)), holds_medium)
        if kind == "disk":
            ang = np.linspace(0.0, 2.0 * math.pi, n + 1)
            ring = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=1)
            tris = np.stack([np.zeros((n, 3)), ring[:-1], ring[1:]], axis=1)
            return _soup(tris, M)
        p0, p1 = p.point("p0", [0.0, 0.0, 0.0]), p.point("p1", [0.0, 0.0, 1.0])
        r = p.number("radius", 1.0)
        if not r > 0 or np.allclose(p0, p1):
            self.doc.fail(el, "a cylinder needs a positive radius and p0 != p1", "fix p0, p1 or the radius")
        tris = cylinder_triangles(p0, p1, r, n)  # open in Mitsuba: without the caps (every 3rd and 4th triangle)
        return _soup(tris.reshape(n, 4, 3, 3)[:, :2].reshape(-1, 3, 3), M)

    def segments(self, centre, radius, holds_medium) -> int:
        """Segments of a curved shape: facets of at most FACET_PIXELS seen from the camera."""
        cam = self.cam
        pixel = math.radians(cam["fov"]) / cam["height"]
        dist = max(float(np.linalg.norm(np.asarray(centre) - cam["position"])) - radius, 0.01 * radius)
        n = math.ceil(2.0 * math.pi * radius / (dist * pixel * FACET_PIXELS))
        n = min(max(n + n % 2, SEGMENTS[0]), SEGMENTS[1])
        return min(n, INTERIOR_SEGMENTS) if holds_medium else n

    def triangles(self, el, p, M) -> dict:
        """An obj or ply mesh under M with Mitsuba's shading normals (src/render/mesh.cpp): the file's vertex
        normals (by M's inverse transpose), else recomputed from the triangles in world space, angle-weighted
        (Thuermer and Wuethrich 1998, as mesh.cpp `recompute_vertex_normals`); none with face_normals."""
        import trimesh

        v, f, vn = self.mesh(el, p)
        out = _triangles(v, f, M)
        if p.boolean("face_normals", False):
            return out
        if vn is None:
            vn = trimesh.Trimesh(np.asarray(out["vertices"]), f, process=False).vertex_normals
        else:
            vn = vn @ np.linalg.inv(M[:3, :3])
        length = np.linalg.norm(vn, axis=1, keepdims=True)
        if np.all(length > 0.0):
            out["normals"] = (vn / length).tolist()
        return out

    def mesh(self, el, p):
        """(vertices, faces, the file's vertex normals or None) of an obj or ply shape."""
        name = p.string("filename")
        if not name:
            self.doc.fail(el, "has no filename", '<string name="filename" value="mesh.obj"/>')
        file = self.doc.resolve(name)  # mesh.cpp: through the resolver as it stands after parsing
        if file is None or not file.is_file():
            self.doc.fail(el, f"mesh file {name!r} not found in {self.doc.searched()}", "fix the filename (relative "
                          "to the main file or a <path>)")
        try:
            v, f, vn = read_mesh(str(file), el.get("type"))
        except Exception as exc:  # trimesh raises many types for unreadable files
            self.doc.fail(el, f"cannot read {file} ({type(exc).__name__}: {exc})", "export it again as OBJ or PLY")
        if len(f) == 0 or not np.all(np.isfinite(v)):
            self.doc.fail(el, f"{file} holds no triangles or non-finite vertices", "fix the mesh file")
        return v, f, vn

    def bsdf(self, el, shape):
        """(reflectance or None, interior fields or None) of a shape's bsdf; Mitsuba's default is a
        diffuse of reflectance 0.5."""
        doc = self.doc
        if el is None:
            return _channels(np.full(3, 0.5)), None
        kind = el.get("type")
        p = _Props(doc, el)
        if kind == "twosided":
            inner = p.nested("bsdf")
            if len(inner) != 1:
                doc.fail(el, "twosided with two different bsdfs is not read", "give twosided one diffuse bsdf")
            p.done()
            if inner[0].get("type") not in ("diffuse",) + COATED:
                doc.fail(inner[0], "twosided wraps a diffuse, plastic or roughplastic bsdf here",
                         'use <bsdf type="diffuse"> inside')
            return self.bsdf(inner[0], shape)
        if kind == "diffuse":
            rho = p.colour("reflectance", 0.5)
            p.done()
            if np.any(rho < 0) or np.any(rho > 1):
                doc.fail(el, "reflectance must be in [0, 1]", "fix the reflectance")
            return _channels(rho), None
        if kind in COATED:  # a diffuse base under a dielectric coat (plastic.cpp, roughplastic.cpp)
            rho = p.colour("diffuse_reflectance", 0.5)
            p.done(ignored=("specular_reflectance", "int_ior", "ext_ior", "nonlinear", "distribution", "alpha",
                            "sample_visible"))
            if np.any(rho < 0) or np.any(rho > 1):
                doc.fail(el, "diffuse_reflectance must be in [0, 1]", "fix the diffuse_reflectance")
            self.notes.append(doc.message(el, f"{kind} read as diffuse of its diffuse_reflectance",
                                          "surfaces here are Lambertian: its specular coat (a highlight that "
                                          "also dims the base) is not rendered"))
            return _channels(rho), None
        if kind == "null":
            p.done()
            return None, {}
        if kind == "dielectric":
            ior = [self.ior(p, k, d) for k, d in (("int_ior", "bk7"), ("ext_ior", "air"))]
            p.done(ignored=("specular_reflectance", "specular_transmittance"))
            return None, {"ior": ior[0] / ior[1]}
        doc.fail(el, f"{kind} bsdfs are not read", "use diffuse, plastic, roughplastic, twosided, null or dielectric")

    def ior(self, p, key, default):
        child = p.values.get(key)
        if child is not None and child.tag == "float":
            value = p.number(key)
        else:
            name = (p.string(key, default) or "").lower()
            if name not in IOR:
                self.doc.fail(child, f"unknown index of refraction {name!r}", "give a number or one of "
                              + ", ".join(IOR))
            value = IOR[name]
        if not value > 0:
            self.doc.fail(child, f"{key} must be positive", "give the index of refraction, e.g. 1.33")
        return value


def _channels(v):
    """One number when the three channels agree, else [r, g, b]."""
    v = [float(x) for x in v]
    return v[0] if v[0] == v[1] == v[2] else v


def _merged(tris):
    """(vertices (V, k), faces (T, 3)) of a (T, 3, k) triangle soup (k = 3, or 6 with normals), equal corners
    merged."""
    v, f = np.unique(np.reshape(tris, (-1, np.shape(tris)[-1])), axis=0, return_inverse=True)
    return v, f.reshape(-1, 3)


def _soup(tris, M) -> dict:
    """An inline triangle mesh from a (T, 3, 3) soup under M."""
    return _triangles(*_merged(tris), M)


def _triangles(v, f, M) -> dict:
    return {"primitive": "triangles", "vertices": _apply(M, v).tolist(), "faces": np.asarray(f).tolist()}


def read_scene(path: Path) -> dict:
    """The scene dict of a Mitsuba 3 XML file (docs/formats/mitsuba.md); UserError on what is not read."""
    problems = Problems(str(path))
    reader = _Reader(Path(path), problems)
    try:
        out = reader.scene()
    except UserError as exc:  # malformed XML, a missing include: reading stops there
        problems.check(fatal=exc)
    problems.check()
    warn(list(dict.fromkeys(reader.notes)), MitsubaNote)
    return out


# ------------------------------------------------------------------------------------------- writing

def _num(x) -> str:
    return repr(float(x))


def _vec(v) -> str:
    return ", ".join(_num(x) for x in v)


def _add(parent, tag, **attrs):
    return ET.SubElement(parent, tag, {k: str(v) for k, v in attrs.items()})


def _rgb(parent, name, value):
    _add(parent, "rgb", name=name, value=_vec(np.broadcast_to(value, 3)))


def _matrix(parent, M):
    _add(_add(parent, "transform", name="to_world"), "matrix", value=" ".join(_num(x) for x in np.ravel(M)))


def _medium(parent, medium, **attrs):
    """A homogeneous medium: sigma_t and albedo = sigma_s / sigma_t (0 where sigma_t = 0), the phase."""
    from ..media.phase import HG, RAYLEIGH

    el = _add(parent, "medium", type="homogeneous", **attrs)
    st = np.asarray(medium.sigma_a + medium.sigma_s, float)
    _rgb(el, "sigma_t", st)
    _rgb(el, "albedo", np.divide(medium.sigma_s, st, out=np.zeros(3), where=st > 0))
    ph = _add(el, "phase", type={HG: "hg", RAYLEIGH: "rayleigh"}.get(medium.phase, "isotropic"))
    if medium.phase == HG:
        _add(ph, "float", name="g", value=_num(medium.g))
    return el


class _Writer:
    """The XML tree and the meshes of one export; `refuse` raises or, with `approximate`, warns."""

    def __init__(self, scene, out: Path, source: str, approximate: bool, emission: dict | None = None):
        self.scene, self.out, self.source, self.approximate = scene, out, source, approximate
        self.emission = emission or {}  # shape index -> {"emission", "two_sided"} (emitters.split)
        self.meshes: list[tuple[str, np.ndarray, np.ndarray | None]] = []  # (file name, triangles, corner normals)

    def refuse(self, key, problem, fix, closest):
        if not self.approximate:
            raise UserError(f"{self.source}: {key}: {problem}, which Mitsuba 3 cannot express; {fix}, or pass "
                            f"--approximate to write {closest}")
        warnings.warn(f"{self.source}: {key}: {problem}; written as {closest} (--approximate)", stacklevel=3)

    def xml(self, raw) -> ET.Element:
        sc, src = self.scene, self.source
        cam = sc.camera
        if cam.type != "perspective":
            raise UserError(f"{src}: camera.type: Mitsuba 3 has no equirectangular sensor; export with --set "
                            'camera.type="perspective"')
        if np.any(sc.background != 0.0):
            raise UserError(f"{src}: background.radiance: Mitsuba's constant emitter would also light the scene; "
                            "set background.radiance = 0 to export")
        if raw.get("render", {}).get("volumetric_shadows") is False:
            self.refuse("render.volumetric_shadows", "false (the medium lit through occluders)",
                        "remove it (Mitsuba always shadows the medium)", "shadowed")
        root = ET.Element("scene", version="3.0.0")
        _add(_add(root, "integrator", type="volpath"), "integer", name="max_depth", value="2")
        med = sc.medium
        if med.has_ground:
            raise UserError(f"{src}: medium.type: a planet's atmosphere is not expressible as a Mitsuba "
                            "homogeneous medium; export a homogeneous or no medium")
        if not med.homogeneous:
            density = med.density_at(cam.position)
            self.refuse("medium.type", med.type_name.replace("_", " "), 'use a homogeneous medium (medium.type = "homogeneous")',
                        f"homogeneous fog of its density at the camera ({density:.4g} x medium.sigma_*)")
            med = copy.copy(med)
            med.sigma_a, med.sigma_s = med.sigma_a * density, med.sigma_s * density
        if med.particles is not None:
            self.refuse("medium.particles", "a particle layer", "remove [medium.particles]", "the medium without it")
        from ..scene.meshes import scene_triangles

        self.tris, self.refl, self.ids, self.normals = scene_triangles(sc, shape_ids=True, normals=True)
        fog = bool(np.any(med.sigma_a + med.sigma_s > 0.0))
        if fog:
            _medium(root, med, id="fog")
        self.sensor(root, fog)
        for i, light in enumerate(sc.lights):
            self.light(root, i, light, raw["light"][i])
        self.shapes(root, fog)
        return root

    def sensor(self, root, fog):
        cam = self.scene.camera
        s = _add(root, "sensor", type="perspective")
        _add(s, "float", name="fov", value=_num(cam.fov))
        _add(s, "string", name="fov_axis", value="y")
        size = self.size()
        _add(s, "float", name="near_clip", value=_num(1e-5 * size))
        _add(s, "float", name="far_clip", value=_num(1e7 * size))
        _add(_add(s, "transform", name="to_world"), "lookat", origin=_vec(cam.position), target=_vec(cam.look_at),
             up=_vec(cam.up))
        if fog:
            _add(s, "ref", id="fog", name="medium")
        _add(_add(s, "sampler", type="independent"), "integer", name="sample_count", value=str(cam.spp))
        film = _add(s, "film", type="hdrfilm")
        _add(film, "integer", name="width", value=str(cam.width))
        _add(film, "integer", name="height", value=str(cam.height))
        _add(film, "string", name="pixel_format", value="rgb")
        _add(film, "rfilter", type="box")  # a pixel is the average over its area, as ours with spp > 1

    def size(self) -> float:
        """The scene's extent (camera, lights, geometry), for the sensor's clip distances."""
        pts = np.concatenate([self.scene.camera.position[None], self.tris.reshape(-1, 3)]
                             + [lt.position[None] for lt in self.scene.lights])
        return max(float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))), 1e-3)

    def light(self, root, i, light, raw):
        from ..lights import DIRECTIONAL, SPOT

        if light.kind == DIRECTIONAL:
            el = _add(root, "emitter", type="directional")
            _add(el, "vector", name="direction", value=_vec(light.axis))
            _rgb(el, "irradiance", light.intensity)
            return
        if light.kind != SPOT:
            el = _add(root, "emitter", type="point")
            _add(el, "point", name="position", value=_vec(light.position))
            _rgb(el, "intensity", light.intensity)
            return
        falloff = raw.get("falloff", "smoothstep")
        if falloff != "mitsuba":
            self.refuse(f"light[{i}].falloff", f'the "{falloff}" spot curve', 'use falloff = "mitsuba" (linear in '
                        "the angle)", "Mitsuba's spot (linear in the angle) with the same angles")
        el = _add(root, "emitter", type="spot")
        helper = np.array([1.0, 0.0, 0.0]) if abs(light.axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        _add(_add(el, "transform", name="to_world"), "lookat", origin=_vec(light.position),
             target=_vec(light.position + light.axis), up=_vec(helper))
        _rgb(el, "intensity", light.intensity)
        _add(el, "float", name="cutoff_angle", value=_num(math.degrees(math.acos(light.cos_end))))
        _add(el, "float", name="beam_width", value=_num(math.degrees(math.acos(light.cos_start))))

    def shapes(self, root, fog):
        from ..scene.meshes import rotation_matrix, world_sphere

        for i, shape in enumerate(self.scene.shapes):
            t = shape.transform
            affine = np.eye(4)
            affine[:3, :3] = rotation_matrix(t.rotate) * t.scale[None, :]
            affine[:3, 3] = t.translate
            tris, refl = self.tris[self.ids == i], self.refl[self.ids == i]
            smooth = shape.smooth and self.normals is not None and (shape.kind in ("mesh", "sphere", "cylinder")
                                                                    or "normals" in shape.params)
            normals = self.normals[self.ids == i] if smooth else None  # (as scene/meshes.py shades them)
            inner = shape.interior
            if inner is not None and i in self.emission:
                raise UserError(f"{self.source}: shape[{i}].emission: an emitting shape that holds a medium cannot "
                                "be exported; put the medium in a shape of its own")
            # a sphere goes out as Mitsuba's where it reads back the same (`_Reader.geometry`): exact (also
            # holding a medium); meshes of spheres as PLY
            sphere = world_sphere(shape) if shape.kind == "sphere" and shape.params["exact"] else None
            if inner is not None:
                el = _add(root, "shape", type="ply") if sphere is None else self.sphere(root, *sphere)
                if sphere is None:
                    self.ply(el, f"{self.out.stem}-{i}.ply", tris)
                if inner.ior != 1.0:
                    self.refuse(f"shape[{i}].interior.ior", f"a refractive interior (ior {inner.ior:g}): volpath at "
                                "max_depth 2 reaches no light and no surface through a refractive boundary",
                                "use ior = 1", "index-matched (a null bsdf)")
                _add(el, "bsdf", type="null")
                _medium(el, inner, name="interior")
                if fog:
                    _add(el, "ref", id="fog", name="exterior")
                continue
            groups = np.unique(refl, axis=0)
            for k, rho in enumerate(groups):
                el = None
                if shape.kind == "box" and not np.any(t.rotate):
                    el = _add(root, "shape", type="cube")
                    lo, hi = shape.params["min"], shape.params["max"]
                    M = np.eye(4)
                    M[:3, :3], M[:3, 3] = np.diag((hi - lo) / 2.0), (hi + lo) / 2.0
                    _matrix(el, affine @ M)
                elif shape.kind == "quad":
                    el = self.rectangle(root, tris)
                elif sphere is not None:
                    el = self.sphere(root, *sphere)
                if el is None:
                    el = _add(root, "shape", type="ply")
                    part = f"-{k}" if len(groups) > 1 else ""
                    mine = np.all(refl == rho, axis=1)
                    self.ply(el, f"{self.out.stem}-{i}{part}.ply", tris[mine], None if normals is None else normals[mine])
                diffuse = _add(_add(el, "bsdf", type="twosided"), "bsdf", type="diffuse")
                _rgb(diffuse, "reflectance", rho)
                if i in self.emission:  # towards each triangle's winding: the PLY's face normals, a cube's outside
                    self.emitter(el, f"shape[{i}]", self.emission[i]["emission"], self.emission[i]["two_sided"])

    @staticmethod
    def sphere(root, centre, radius):
        """Mitsuba's sphere of this centre and radius."""
        el = _add(root, "shape", type="sphere")
        _add(el, "point", name="center", value=_vec(centre))
        _add(el, "float", name="radius", value=_num(radius))
        return el

    def emitter(self, el, key, radiance, two_sided):
        """A one-sided area emitter in the shape `el` (mitsuba3 src/emitters/area.cpp)."""
        if two_sided:
            self.refuse(f"{key}.two_sided", "a two-sided emitter (Mitsuba's area emitter is one-sided)",
                        "set two_sided = false", "one-sided")
        _rgb(_add(el, "emitter", type="area"), "radiance", emitters.colour(radiance, f"{key}.radiance", self.source))

    def area_lights(self, root, lights):
        """Quad, disk and sphere lights as black diffuse rectangles, disks and spheres with an area emitter;
        the environment as a constant or envmap emitter (the inverse of `_Reader.area_light`, `environment`)."""
        src = self.source
        for i, light in lights:
            key, kind = f"light[{i}]", light.get("type")
            if kind == "environment":
                self.environment(root, key, light)
                continue
            el = _add(root, "shape", type={"quad": "rectangle"}.get(kind, kind))
            M = np.eye(4)
            if kind == "quad":
                M[:3, 3], M[:3, 0], M[:3, 1], M[:3, 2] = emitters.quad_frame(light.get("corners"), f"{key}.corners", src)
                _matrix(el, M)
            elif kind == "disk":
                M, r = emitters.disk_frame(light, key, src)
                M[:3, :2] *= r
                _matrix(el, M)
            else:
                _add(el, "point", name="center", value=_vec(emitters.vector(light.get("center"), f"{key}.center", src)))
                _add(el, "float", name="radius", value=_num(emitters.positive(light.get("radius"), f"{key}.radius", src)))
            _rgb(_add(el, "bsdf", type="diffuse"), "reflectance", 0.0)  # the emitter is black where it does not emit
            self.emitter(el, key, light.get("radiance"), light.get("two_sided", False))

    def environment(self, root, key, light):
        """A constant emitter, or an equirectangular map interpolated as Mitsuba's (filter "mitsuba") as an
        envmap; other filters only with --approximate (Mitsuba interpolates every map its way), an
        octahedral map not at all."""
        src = self.source
        if "map" not in light:
            _rgb(_add(root, "emitter", type="constant"), "radiance", emitters.constant_environment(light, key, src))
            return
        from ..lights import environment
        from ..scene.assets import find_asset
        from ..scene.meshes import rotation_matrix

        if light.get("mapping", "equirectangular") != "equirectangular":
            raise UserError(f"{src}: {key}.mapping: Mitsuba 3's envmap is equirectangular, and resampling an "
                            "octahedral map into one is not exact; export to pbrt-v4")
        filt = light.get("filter", "nearest")
        if filt != "mitsuba":
            self.refuse(f"{key}.filter", f'a map looked up "{filt}" (Mitsuba interpolates it bilinearly, its first '
                        "and last rows on the poles)", 'set filter = "mitsuba"', "Mitsuba's interpolation of the map")
        file = find_asset(str(light["map"]), self.scene.path, f"{key}.map", "environment map")  # as the reader finds it
        el = _add(root, "emitter", type="envmap")
        _add(el, "string", name="filename", value=str(file.resolve()))
        _add(el, "float", name="scale", value=_num(emitters.positive(light.get("scale", 1.0), f"{key}.scale", src)))
        M = np.eye(4)
        M[:3, :3] = rotation_matrix(emitters.vector(light.get("rotate", [0.0, 0.0, 0.0]), f"{key}.rotate", src)) @ \
            (environment.MIRROR if light.get("mirror") is True else np.eye(3)) @ \
            np.diag([-1.0, 1.0, -1.0])  # Mitsuba's u = 0 is our map's centre column (`_Reader.environment`)
        _matrix(el, M)

    @staticmethod
    def rectangle(root, tris):
        """A parallelogram quad (triangles c0 c1 c2, c0 c2 c3) as Mitsuba's rectangle, else None."""
        c0, c1, c2 = tris[0]
        c3 = tris[1][2]
        x, y = (c1 - c0) / 2.0, (c3 - c0) / 2.0
        n = np.cross(x, y)
        if not np.allclose(c0 + c2, c1 + c3, rtol=0, atol=1e-12 * np.abs(tris).max()) or not np.any(n):
            return None
        el = _add(root, "shape", type="rectangle")
        M = np.eye(4)
        M[:3, 0], M[:3, 1], M[:3, 2], M[:3, 3] = x, y, n / np.linalg.norm(n), (c0 + c2) / 2.0
        _matrix(el, M)
        return el

    def ply(self, el, name, tris, normals=None):
        _add(el, "string", name="filename", value=name)
        if normals is None:
            _add(el, "boolean", name="face_normals", value="true")  # flat, as ours
        self.meshes.append((name, tris, normals))


def _ply_bytes(tris, normals=None) -> bytes:
    """A binary little-endian PLY of a triangle soup (equal corners merged): float32 vertices, and the
    corners' shading normals (T, 3, 3) as nx, ny, nz when given."""
    if normals is None:
        v, f = _merged(tris)
    else:
        v, f = _merged(np.concatenate([tris, normals], axis=2))
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\nproperty float x\nproperty float y\n"
            f"property float z\n" + ("property float nx\nproperty float ny\nproperty float nz\n" if normals is not None
                                     else "") + f"element face {len(f)}\nproperty list uchar uint vertex_indices\n"
            "end_header\n")
    faces = np.zeros(len(f), dtype=[("n", "u1"), ("i", "<u4", 3)])
    faces["n"], faces["i"] = 3, f
    return head.encode() + v.astype("<f4").tobytes() + faces.tobytes()


def export(raw: dict, out: Path, source: str, approximate: bool) -> list[Path]:
    """Write `raw` as a Mitsuba 3 scene `out` (.xml) and its meshes beside it; returns the files written.
    Nothing is written when the scene cannot be expressed (UserError)."""
    from ..scene.format import scene_from_dict

    out = Path(out)
    if out.suffix.lower() != ".xml":
        raise UserError(f"{source}: --out {out}: a Mitsuba scene is an .xml file; name it scene.xml")
    path = Path(source) if Path(source).is_file() else None
    rest, lights, emission = emitters.split(raw)
    writer = _Writer(scene_from_dict(copy.deepcopy(rest), source, path), out, source, approximate, emission)
    root = writer.xml(rest)
    writer.area_lights(root, lights)
    ET.indent(root)
    files = [(out, ET.tostring(root, encoding="unicode").encode() + b"\n")]
    files += [(out.parent / name, _ply_bytes(tris, normals)) for name, tris, normals in writer.meshes]
    temps = []
    try:
        for target, data in files:
            tmp = target.with_name(f".{target.name}.tmp{os.getpid()}")
            temps.append(tmp)
            tmp.write_bytes(data)
        for (target, _), tmp in zip(files, temps):
            os.replace(tmp, target)
    except OSError as exc:
        for tmp in temps:
            tmp.unlink(missing_ok=True)
        raise UserError(f"{source}: --out {out}: cannot write ({exc.strerror}); check the folder and its "
                        "permissions") from None
    return [target for target, _ in files]
