"""pbrt-v4 scenes (docs/formats/pbrt.md): the subset a fog scene uses, read into the scene dict and
written from it.

Units and conventions follow pbrt-v4's sources (src/pbrt/lights.cpp `PointLight::Create`,
`SpotLight::Create`, `DistantLight::Create`; util/spectrum.cpp `SpectrumToPhotometric`;
cameras.cpp `PerspectiveCamera::Create`, `SphericalCamera::GenerateRay`; util/transform.cpp `LookAt`):

- An "rgb" light spectrum is divided by its illuminant's luminance, so pbrt's RGB output of
  `"rgb I" [r g b]` with `scale` s is s (r, g, b): our W/sr per channel. `power` P multiplies by
  P / k_e (point: k_e = 4 pi; spot: 2 pi ((1 - cos_start) + (cos_start - cos_end) / 2), the RGB
  multiplier not normalised away, as pbrt); a distant light's `illuminance` E multiplies by E.
- `fov` spans the shorter image axis; ours is vertical.
- pbrt's LookAt makes camera x = up x dir: seen from a right-handed world, a plain LookAt image is
  mirrored. A file whose camera is mirrored this way is read with world x negated everywhere, so
  our image equals pbrt's; we write `Scale -1 1 1` before LookAt, so nothing is mirrored.
"""
from __future__ import annotations

import gzip
import io as _io
import math
import re
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import UserError, counted
from . import emitters, loop
from .meshfile import read_mesh
from .report import ImportNote, Problems, every

SPHERE_SEGMENTS = 64  # a pbrt sphere becomes our exact sphere (its mesh rows: this many segments)
MAX_INCLUDE_DEPTH = 32
PATCH_GRID = 16  # a non-planar bilinear patch is tessellated into PATCH_GRID^2 quads
MAX_SUBDIVIDED = 1 << 24  # the most triangles a "loopsubdiv" may make (each 4^levels of its control mesh)
ORTHO_REFUSE, ORTHO_NOTE = 1e-3, 1e-6  # the camera transform's axes: orthonormal to this (relative), else refused / noted
HG_MAX = 0.99  # pbrt-v4 clamps HG's g to [-0.99, 0.99] (util/scattering.h HenyeyGreenstein)
MAX_POWER_PARTS = 4096  # an area light's "power" on a mesh of unequal triangles: at most this many shapes



class PbrtNote(ImportNote):
    """What a pbrt-v4 import reads approximately or converts, one line each."""


# ---------------------------------------------------------------------------------------------- tokens

_TOKEN = re.compile(r'[ \t\r\n]+|#[^\r\n]*|"(?:[^"\\\n]|\\.)*"|\[|\]|[^ \t\r\n"\[\]]+|"')
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_ESCAPES = {"b": "\b", "f": "\f", "n": "\n", "r": "\r", "t": "\t", "\\": "\\", "'": "'", '"': '"'}


@dataclass
class Token:
    kind: str  # "str" (a quoted string, unescaped), "[", "]" or "word" (a number, a directive, true/false)
    value: str
    line: int


def tokenize(text: str, source: str) -> list[Token]:
    """pbrt-v4's tokens (parser.cpp `Tokenizer::Next`) with their line numbers; comments dropped."""
    tokens, line = [], 1
    for m in _TOKEN.finditer(text):
        s = m.group()
        c = s[0]
        if c in " \t\r\n":
            line += s.count("\n")
        elif c == "#":
            continue
        elif c == '"':
            if len(s) == 1:
                raise UserError(f"{source}:{line}: unterminated string; close it with \" on the same line")
            tokens.append(Token("str", _unescape(s[1:-1], source, line), line))
        elif c in "[]":
            tokens.append(Token(c, c, line))
        else:
            tokens.append(Token("word", s, line))
    return tokens


def _unescape(s: str, source: str, line: int) -> str:
    if "\\" not in s:
        return s
    out, i = [], 0
    while i < len(s):
        if s[i] == "\\":
            if s[i + 1] not in _ESCAPES:
                raise UserError(f"{source}:{line}: unknown escape \\{s[i + 1]} in a string; use \\\\ for a backslash")
            out.append(_ESCAPES[s[i + 1]])
            i += 2
        else:
            out.append(s[i])
            i += 1
    return "".join(out)


# ------------------------------------------------------------------------------------------ parameters

SPECTRUM_TYPES = ("rgb", "spectrum", "blackbody")
PARAM_TYPES = ("integer", "float", "point2", "vector2", "point3", "vector3", "normal", "normal3", "bool", "string",
               "texture") + SPECTRUM_TYPES


@dataclass
class Param:
    type: str
    name: str
    values: list  # Tokens
    line: int


class _Where:
    """The file being read, to build messages `file:line: what; fix`."""

    def __init__(self, path: Path):
        self.path = path

    def message(self, line: int, what: str, fix: str) -> str:
        return f"{self.path}:{line}: {what}; {fix}"

    def fail(self, line: int, what: str, fix: str):
        raise UserError(self.message(line, what, fix))

    def number(self, tok: Token, what: str) -> float:
        if tok.kind != "word" or not _NUMBER.fullmatch(tok.value):
            if tok.kind == "word" and tok.value.lower().lstrip("+-") in ("nan", "inf", "infinity"):
                self.fail(tok.line, f"{what}: {tok.value} is not a finite number", "write a finite number")
            self.fail(tok.line, f"{what}: expected a number, got {_show(tok)}", "write a number such as 1.0")
        v = float(tok.value)
        if not math.isfinite(v):
            self.fail(tok.line, f"{what}: {tok.value} is not a finite number", "write a number within float range")
        return v


def _show(tok: Token) -> str:
    return f'"{tok.value}"' if tok.kind == "str" else tok.value


class Params:
    """A directive's parameter list; each `take` consumes one, `done` refuses the rest (pbrt-v4 stops on
    an unused parameter too: paramdict.cpp `ReportUnused`)."""

    def __init__(self, where: _Where, directive: str, line: int, params: dict[str, Param]):
        self.where, self.directive, self.line, self.params = where, directive, line, params

    def has(self, name):
        return name in self.params

    def _take(self, name, types):
        p = self.params.pop(name, None)
        if p is not None and p.type not in types:
            kind = "a non-RGB spectrum" if p.type in SPECTRUM_TYPES else f"type {p.type}"
            fix = 'give it as "rgb ' + name + '" [r g b]' if "rgb" in types else f'declare it as "{types[0]} {name}"'
            self.where.fail(p.line, f'{self.directive}: "{p.type} {name}" is {kind}, which is not read', fix)
        return p

    def floats(self, name, types, count=None, default=None):
        p = self._take(name, types)
        if p is None:
            return default
        v = [self.where.number(t, f'{self.directive} "{name}"') for t in p.values]
        if count is not None and len(v) != count or count is None and len(v) % 3:
            n = counted(count, "value") if count is not None else "a multiple of 3 values"
            self.where.fail(p.line, f'{self.directive}: "{name}" needs {n}, got {len(v)}', "give that many numbers")
        return v

    def one(self, name, default, types=("float",)):
        v = self.floats(name, types, 1)
        return default if v is None else v[0]

    def ints(self, name, default=None):
        p = self._take(name, ("integer",))
        if p is None:
            return default
        out = []
        for t in p.values:
            if t.kind != "word" or not re.fullmatch(r"[+-]?\d+", t.value):
                self.where.fail(t.line, f'{self.directive} "integer {name}": {_show(t)} is not an integer',
                                "write whole numbers")
            out.append(int(t.value))
        return out

    def string(self, name, default=None):
        p = self._take(name, ("string",))
        if p is None:
            return default
        if len(p.values) != 1 or p.values[0].kind != "str":
            self.where.fail(p.line, f'{self.directive}: "string {name}" needs one quoted string', f'write "string {name}" "..."')
        return p.values[0].value

    def rgb(self, name, default, albedo=False):
        """An "rgb" spectrum (pbrt-v4 paramdict.cpp `extractSpectrumArray`: no component below 0; an albedo
        none above 1)."""
        v = self.floats(name, ("rgb",), 3)
        if v is None:
            return default
        if min(v) < 0.0 or albedo and max(v) > 1.0:
            self.where.fail(self.line, f'{self.directive}: "rgb {name}" {v} is outside {"[0, 1]" if albedo else "[0, inf)"}',
                            "use non-negative values" + (" at most 1" if albedo else ""))
        return v

    def boolean(self, name, default=False):
        """A "bool" parameter: true or false, bare or quoted (parser.cpp)."""
        p = self._take(name, ("bool",))
        if p is None:
            return default
        if len(p.values) != 1 or p.values[0].value not in ("true", "false"):
            self.where.fail(p.line, f'{self.directive}: "bool {name}" needs true or false', f'write "bool {name}" true')
        return p.values[0].value == "true"

    def ignore(self, *names):
        for n in names:
            self.params.pop(n, None)

    def done(self):
        """Refuse the parameters not taken, all of them at once."""
        every([self.where.message(p.line, f'{self.directive}: parameter "{p.type} {p.name}" is not read by this '
                                  "importer", "remove it (docs/formats/pbrt.md lists what is read)")
               for p in self.params.values()])


# --------------------------------------------------------------------------------------------- reading


def _translate(v):
    m = np.eye(4)
    m[:3, 3] = v
    return m


def _rotate(deg, axis):
    """pbrt-v4 util/transform.h `Rotate`: `deg` about `axis`, counter-clockwise looking down the axis."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    m = np.eye(4)
    m[:3, :3] = c * np.eye(3) + s * k + (1.0 - c) * np.outer(a, a)
    return m


def _world_from_look_at(eye, look, up):
    """The inverse of pbrt-v4's LookAt matrix: columns right = up x dir, newUp = dir x right, dir, eye."""
    d = look - eye
    d = d / np.linalg.norm(d)
    right = np.cross(up / np.linalg.norm(up), d)
    right /= np.linalg.norm(right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, np.cross(d, right), d, eye
    return m


@dataclass
class _State:
    """pbrt's graphics state: what AttributeBegin saves."""
    ctm: np.ndarray = field(default_factory=lambda: np.eye(4))
    inv: np.ndarray = field(default_factory=lambda: np.eye(4))  # its inverse, kept exact as pbrt's Transform does
    material: tuple = ("diffuse", [0.5, 0.5, 0.5])
    inside: str = ""
    outside: str = ""
    area: dict | None = None  # the AreaLightSource for the shapes that follow (`_Reader._AreaLightSource`)
    reverse: bool = False  # ReverseOrientation: the emitting side turned

    def copy(self):
        return _State(self.ctm.copy(), self.inv.copy(), self.material, self.inside, self.outside, self.area,
                      self.reverse)

    def concat(self, m, inv):
        self.ctm, self.inv = self.ctm @ m, inv @ self.inv

    def set(self, m, inv=None):
        if inv is None:
            with np.errstate(all="ignore"):
                inv = np.linalg.pinv(m)  # a singular transform is refused where it is used (`_Reader._affine`)
        self.ctm, self.inv = m.copy(), inv.copy()


OPTION_DIRECTIVES = {"Camera", "Film", "Sampler", "Integrator", "PixelFilter", "Accelerator", "ColorSpace", "Option"}
WORLD_DIRECTIVES = {"AttributeBegin", "AttributeEnd", "TransformBegin", "TransformEnd", "Shape", "Material",
                    "MakeNamedMaterial", "NamedMaterial", "LightSource", "AreaLightSource", "ReverseOrientation",
                    "Import"}
REFUSED = {"Texture": "textures", "ObjectBegin": "object instancing",
           "ObjectEnd": "object instancing", "ObjectInstance": "object instancing", "Attribute": "attribute defaults",
           "TransformTimes": "motion blur", "ActiveTransform": "motion blur",
           "WorldEnd": "pbrt-v3 syntax (run `pbrt --upgrade`)"}


class _Reader:
    def __init__(self, main: Path, problems: Problems):
        self.main, self.problems = main, problems
        self.state = _State()
        self.stack: list[tuple[_State, int, Path]] = []
        self.world = False
        self.named_cs: dict[str, tuple] = {}  # name -> (CTM, its inverse)
        self.materials: dict[str, tuple] = {}
        self.media: dict[str, tuple] = {}  # name -> (dict of our medium keys, file, line)
        self.camera = None
        self.screen, self.exposure, self.iso = (None, None), 1.0, 100.0
        self.notes: list[str] = []  # what is read approximately, said once each (`read_scene` warns)
        self.film = (1280, 720)
        self.spp = 16
        self.shapes: list[dict] = []  # pbrt world coordinates; their "_material", "_media" resolved at the end
        self.lights: list[dict] = []
        self.files: list[Path] = []

    # --- files
    def run(self, path: Path, line: int = 0, where: _Where | None = None):
        real = path.resolve()
        if real in self.files:
            chain = " -> ".join(str(f.name) for f in self.files + [real])
            where.fail(line, f"Include loop ({chain})", "remove the Include or Import that reads a file already open")
        if len(self.files) >= MAX_INCLUDE_DEPTH:
            where.fail(line, f"Include nested deeper than {MAX_INCLUDE_DEPTH} files", "flatten the includes")
        try:
            data = path.read_bytes()
            text = (gzip.decompress(data) if path.suffix == ".gz" else data).decode("utf-8")
        except FileNotFoundError:
            if where is None:
                raise UserError(f"{path}: no such scene file; check the path") from None
            where.fail(line, f'included file "{path}" not found', "check the file name (relative to the main file)")
        except (OSError, UnicodeDecodeError, gzip.BadGzipFile) as exc:
            raise UserError(f"{path}: cannot read the pbrt file ({exc}); check its permissions and encoding") from None
        self.files.append(real)
        w = _Where(path)
        self._directives(tokenize(text, str(path)), w)
        self.files.pop()

    def resolve(self, name: str) -> Path:
        """pbrt-v4 util/file.cpp `ResolveFilename`: relative to the main file's folder."""
        p = Path(name)
        return p if p.is_absolute() else self.main.parent / p

    # --- directives
    def _directives(self, toks: list[Token], w: _Where):
        i, n = 0, len(toks)

        def take(what):
            nonlocal i
            if i >= n:
                w.fail(toks[-1].line, f"{what}: unexpected end of file", "complete the directive")
            i += 1
            return toks[i - 1]

        def numbers(d, count, bracketed=False):
            if bracketed and take(d).kind != "[":
                w.fail(toks[i - 1].line, f"{d}: expected [ and {count} numbers", f"write {d} [ ... ]")
            v = [w.number(take(d), d) for _ in range(count)]
            if bracketed and take(d).kind != "]":
                w.fail(toks[i - 1].line, f"{d}: expected ] after {count} numbers", "give exactly 16 numbers")
            return np.array(v)

        def quoted(d):
            t = take(d)
            if t.kind != "str":
                w.fail(t.line, f"{d}: expected a quoted name, got {_show(t)}", f'write {d} "name"')
            return t.value

        def skip():
            """Past a refused directive's arguments, to the next directive (pbrt's are capitalised)."""
            nonlocal i
            while i < n and not (toks[i].kind == "word" and toks[i].value[:1].isupper()):
                i += 1

        def params(d, line):
            nonlocal i
            out = {}
            while i < n and toks[i].kind == "str":
                decl = toks[i]
                i += 1
                parts = decl.value.split()
                if len(parts) != 2 or parts[0] not in PARAM_TYPES:
                    w.fail(decl.line, f'{d}: "{decl.value}" is not a parameter declaration "type name"',
                           "write e.g. \"float fov\" (types: " + ", ".join(PARAM_TYPES) + ")")
                if parts[1] in out:
                    w.fail(decl.line, f'{d}: parameter "{parts[1]}" given twice', "remove one")
                if i < n and toks[i].kind == "[":
                    i += 1
                    vals = []
                    while True:
                        t = take(d)
                        if t.kind == "]":
                            break
                        if t.kind == "[":
                            w.fail(t.line, f"{d}: nested [", "close the list with ]")
                        vals.append(t)
                else:
                    vals = [take(d)]
                out[parts[1]] = Param(parts[0], parts[1], vals, decl.line)
            return Params(w, d, line, out)

        while i < n:
            tok = take("")
            d, line = tok.value, tok.line
            if tok.kind != "word" or not d[:1].isalpha():
                w.fail(line, f"expected a directive, got {_show(tok)}", "check the previous directive's parameters")
            misplaced = (d in OPTION_DIRECTIVES and self.world and (f"{d} after WorldBegin", "move it before WorldBegin")
                         or d in WORLD_DIRECTIVES and not self.world and (f"{d} before WorldBegin",
                                                                          "move it after WorldBegin"))
            if d in REFUSED or misplaced:  # listed; reading goes on at the next directive
                with self.problems.each():
                    w.fail(line, *(misplaced or (f"{d} ({REFUSED[d]}) is not read",
                                                 "remove it (docs/formats/pbrt.md lists what is read)")))
                skip()
                continue
            st = self.state
            if d == "LookAt":
                v = numbers(d, 9)
                eye, look, up = v[:3], v[3:6], v[6:]
                dirn = look - eye
                if not np.linalg.norm(dirn) > 0 or not np.linalg.norm(np.cross(up, dirn)) > 0:
                    w.fail(line, "LookAt: the eye equals the look point, or up is zero or along the view direction",
                           "give a look point away from the eye and an up vector across the view")
                wfc = _world_from_look_at(eye, look, up)
                st.concat(np.linalg.inv(wfc), wfc)
            elif d == "Translate":
                v = numbers(d, 3)
                st.concat(_translate(v), _translate(-v))
            elif d == "Scale":
                v = numbers(d, 3)
                if not np.all(v != 0):
                    w.fail(line, "Scale: a zero factor flattens everything after it", "use non-zero factors")
                st.concat(np.diag([*v, 1.0]), np.diag([*(1.0 / v), 1.0]))
            elif d == "Rotate":
                v = numbers(d, 4)
                if not np.linalg.norm(v[1:]) > 0:
                    w.fail(line, "Rotate: the axis is zero", "give a non-zero axis")
                r = _rotate(v[0], v[1:])
                st.concat(r, r.T)
            elif d in ("Transform", "ConcatTransform"):
                m = numbers(d, 16, bracketed=True).reshape(4, 4).T  # the file lists the matrix column by column
                st.set(m if d == "Transform" else st.ctm @ m)
            elif d == "Identity":
                st.set(np.eye(4), np.eye(4))
            elif d == "CoordinateSystem":
                self.named_cs[quoted(d)] = (st.ctm.copy(), st.inv.copy())
            elif d == "CoordSysTransform":
                name = quoted(d)
                if name not in self.named_cs:
                    w.fail(line, f'CoordSysTransform: no coordinate system "{name}"',
                           f'define it with CoordinateSystem "{name}" first (or use "camera" after Camera)')
                st.set(*self.named_cs[name])
            elif d in ("AttributeBegin", "TransformBegin"):
                self.stack.append((self.state.copy(), line, w.path))
            elif d in ("AttributeEnd", "TransformEnd"):
                if not self.stack:
                    w.fail(line, f"{d} without a matching AttributeBegin", "remove it or add the AttributeBegin")
                self.state = self.stack.pop()[0]
            elif d == "ReverseOrientation":
                st.reverse = not st.reverse  # the side an area light emits to (our surfaces reflect on both)
            elif d == "WorldBegin":
                if self.world:
                    w.fail(line, "a second WorldBegin", "remove it")
                if self.camera is None and not self.problems.items:  # (else the Camera was refused: listed)
                    w.fail(line, "WorldBegin before any Camera", 'add LookAt ... and Camera "perspective" before it')
                self.world = True
                st.set(np.eye(4), np.eye(4))
                self.named_cs["world"] = (np.eye(4), np.eye(4))
            elif d in ("Include", "Import"):
                sub = self.resolve(quoted(d))
                saved = self.state.copy() if d == "Import" else None
                self.run(sub, line, w)
                if saved is not None:  # pbrt-v4 imports with a copy of the graphics state
                    self.state = saved
            elif d == "MediumInterface":
                inside = quoted(d)
                outside = toks[i].value if i < n and toks[i].kind == "str" else inside
                i += i < n and toks[i].kind == "str"
                self.state.inside, self.state.outside = inside, outside
            elif d == "NamedMaterial":
                name = quoted(d)
                if name not in self.materials:
                    w.fail(line, f'NamedMaterial: no material "{name}"', f'define it with MakeNamedMaterial "{name}" first')
                self.state.material = self.materials[name]
            elif d in ("Camera", "Film", "Sampler", "Integrator", "PixelFilter", "Accelerator", "ColorSpace",
                       "Shape", "Material", "LightSource", "AreaLightSource", "MakeNamedMaterial", "MakeNamedMedium",
                       "Option"):
                name = quoted(d)
                if d == "ColorSpace":
                    if name != "srgb":
                        w.fail(line, f'ColorSpace "{name}" is not read', 'use "srgb" (our RGB channels are linear sRGB)')
                    continue
                if d == "Option":
                    take(d)  # render options (pixel jitter, wavelengths, ...) do not change the scene
                    continue
                given = params(f'{d} "{name}"', line)
                with self.problems.each():  # a directive that cannot be read is listed and left out
                    try:
                        getattr(self, "_" + d)(name, given, w, line)
                    except UserError:
                        if d == "MakeNamedMaterial":  # stand-ins, so that what names them adds no problem
                            self.materials.setdefault(name, ("diffuse", [0.5] * 3))
                        elif d == "MakeNamedMedium":
                            self.media.setdefault(name, (None, w.path, line))
                        raise
            else:
                w.fail(line, f"unknown directive {d}", "check its spelling (pbrt-v4 directives are case-sensitive)")

    # --- options
    def _Camera(self, kind, p, w, line):
        if kind not in ("perspective", "spherical"):
            w.fail(line, f'Camera "{kind}" is not read', 'use "perspective" or "spherical" (equirectangular)')
        self._affine(w, line, "Camera")
        m = self.state.inv
        self.named_cs["camera"] = (m.copy(), self.state.ctm.copy())
        if kind == "perspective":
            fov = p.one("fov", 90.0)
            if not 0.0 < fov < 180.0:
                w.fail(line, f'Camera "perspective": fov {fov:g} is outside (0, 180) degrees', "use e.g. 45")
        else:
            if p.string("mapping", "equalarea") != "equirectangular":
                w.fail(line, 'Camera "spherical": only "string mapping" "equirectangular" is read',
                       "use the equirectangular mapping (ours); equalarea has no counterpart")
            fov = None
        # cameras.cpp PerspectiveCamera::Create: the screen window (default: the shorter image axis spans
        # [-1, 1], frameaspectratio the film's) is where the image lies on the plane at tan(fov / 2)
        window = p.floats("screenwindow", ("float",), 4)
        frame = p.one("frameaspectratio", None)
        if kind == "perspective" and p.one("lensradius", 0.0) != 0.0:
            w.fail(line, f'{p.directive}: "lensradius" > 0 (depth of field) is not read', "remove it (a pinhole camera)")
        p.ignore("focaldistance", "lensradius")  # no effect without a lens (the spherical camera reads none of these)
        # scene.cpp: the film's exposure time is shutterclose - shutteropen (a scale of the image: `scene`)
        exposure = p.one("shutterclose", 1.0) - p.one("shutteropen", 0.0)
        if not exposure > 0.0:
            w.fail(line, f"{p.directive}: shutterclose - shutteropen = {exposure:g}: the shutter does not open (pbrt "
                   "stops here too)", "give shutterclose > shutteropen, or leave both out (0 and 1)")
        p.done()
        self.camera = (kind, m, fov, self.state.outside, w.path, line)
        self.screen, self.exposure = (window, frame) if kind == "perspective" else (None, None), exposure

    def _Film(self, kind, p, w, line):
        if kind not in ("rgb", "gbuffer", "spectral"):
            w.fail(line, f'Film "{kind}" is not read', 'use "rgb"')
        x, y = p.ints("xresolution", [1280]), p.ints("yresolution", [720])
        if len(x) != 1 or len(y) != 1 or x[0] < 1 or y[0] < 1:
            w.fail(line, "Film: xresolution and yresolution must be one positive integer each", "e.g. [ 640 ] and [ 480 ]")
        # film.cpp PixelSensor::Create: imagingRatio = exposureTime * iso / 100 scales the image; the default
        # sensor "cie1931" with whitebalance 0 passes the scene's RGB through unchanged
        iso = p.one("iso", 100.0)
        if not iso > 0.0:
            w.fail(line, f'{p.directive}: "iso" {iso:g} must be positive', "give the ISO speed, e.g. 100 (pbrt's default)")
        sensor = p.string("sensor", "cie1931")
        balance = p.one("whitebalance", 0.0)
        if sensor != "cie1931":
            w.fail(line, f'{p.directive}: sensor "{sensor}": a camera\'s spectral response (and its white balance, 6500 K '
                   "by default) changes the colours, which is not modelled", 'remove it (pbrt\'s default "cie1931")')
        if balance != 0.0:
            w.fail(line, f'{p.directive}: whitebalance {balance:g}: a von Kries adaptation from a {balance:g} K daylight '
                   "white changes the colours, which is not modelled", "remove it (0, pbrt's default: no white balance)")
        p.ignore("filename", "savefp16")
        p.done()
        self.film, self.iso = (x[0], y[0]), iso

    def _Sampler(self, kind, p, w, line):
        if kind == "stratified":
            n = p.ints("xsamples", [4])[0] * p.ints("ysamples", [4])[0]
        else:
            n = p.ints("pixelsamples", [4 if kind == "independent" else 16])[0]  # samplers.cpp: the defaults
        if n < 1:
            w.fail(line, f"{p.directive}: {n} samples per pixel", "use at least 1")
        self.spp = n  # the other sampler parameters only change pbrt's noise

    def _Integrator(self, kind, p, w, line):
        pass  # we compute single scattering whatever pbrt's integrator (docs/formats/pbrt.md)

    _PixelFilter = _Accelerator = _Integrator  # our pixel is the box average; acceleration does not change the image

    # --- world
    def _affine(self, w, line, what):
        m = self.state.ctm
        if not np.allclose(m[3], [0, 0, 0, 1]) or not abs(np.linalg.det(m[:3, :3])) > 0:
            w.fail(line, f"{what}: the current transform is projective or singular", "use an invertible affine transform")
        return m

    def _material(self, kind, p, w, line):
        if kind == "diffuse":
            mat = ("diffuse", p.rgb("reflectance", [0.5, 0.5, 0.5], albedo=True))
        elif kind == "interface":
            mat = ("interface",)
        elif kind == "dielectric":
            eta = p.one("eta", 1.5)
            if not eta > 0.0:
                w.fail(line, f"{p.directive}: eta {eta:g} must be positive", "use e.g. 1.33 for water")
            for r in ("roughness", "uroughness", "vroughness"):
                if p.one(r, 0.0) != 0.0:
                    w.fail(line, f'{p.directive}: "{r}" > 0 (a rough dielectric) is not read', "use a smooth one (0)")
            p.ignore("remaproughness")
            mat = ("dielectric", eta)
        elif kind == "coateddiffuse":  # materials.cpp CoatedDiffuseMaterial::Create: a diffuse base under a coat
            mat = ("diffuse", p.rgb("reflectance", [0.5, 0.5, 0.5], albedo=True))
            p.ignore("roughness", "uroughness", "vroughness", "remaproughness", "thickness", "eta", "albedo", "g",
                     "maxdepth", "nsamples")
            self.notes.append(f'{w.path}:{line}: {p.directive}: "coateddiffuse" read as "diffuse" of its reflectance '
                              "(surfaces here are Lambertian: its dielectric coat, a glossy highlight that also "
                              "dims the base, is not rendered)")
        else:
            w.fail(line, f'Material "{kind}" is not read', 'use "diffuse", "coateddiffuse", "interface" or "dielectric"')
        p.done()
        return mat

    def _Material(self, kind, p, w, line):
        self.state.material = self._material(kind, p, w, line)

    def _MakeNamedMaterial(self, name, p, w, line):
        kind = p.string("type")
        if kind is None:
            w.fail(line, f'{p.directive}: no "string type"', 'add "string type" "diffuse"')
        self.materials[name] = self._material(kind, p, w, line)

    def _MakeNamedMedium(self, name, p, w, line):
        kind = p.string("type")
        if kind != "homogeneous":
            w.fail(line, f'{p.directive}: medium type "{kind}" is not read', 'use "string type" "homogeneous"')
        if name in self.media:
            w.fail(line, f'{p.directive}: medium "{name}" defined twice', "rename one")
        sa = p.rgb("sigma_a", [1.0, 1.0, 1.0])  # pbrt-v4 media.cpp HomogeneousMedium::Create: both default to 1
        ss = p.rgb("sigma_s", [1.0, 1.0, 1.0])
        scale = p.one("scale", 1.0)
        g = p.one("g", 0.0)
        if scale < 0.0 or not abs(g) <= 1.0:
            w.fail(line, f"{p.directive}: needs scale >= 0 and |g| <= 1, got scale {scale:g}, g {g:g}", "fix the value")
        g = min(max(g, -HG_MAX), HG_MAX)  # as pbrt renders it
        p.done()
        medium = {"sigma_a": [scale * v for v in sa], "sigma_s": [scale * v for v in ss],
                  "phase": "isotropic" if g == 0.0 else {"type": "hg", "g": g}}
        self.media[name] = (medium, w.path, line)

    def _LightSource(self, kind, p, w, line):
        m = self._affine(w, line, p.directive)
        scale = p.one("scale", 1.0)
        if kind in ("point", "spot"):
            rgb = p.rgb("I", [1.0, 1.0, 1.0])
            power = p.one("power", -1.0)
            frm = np.array(p.floats("from", ("point3",), 3, [0.0, 0.0, 0.0]))
            light = {"type": kind, "position": m[:3, :3] @ frm + m[:3, 3]}
            if kind == "point":
                k_e = 4.0 * math.pi  # lights.cpp PointLight::Create
            else:
                to = np.array(p.floats("to", ("point3",), 3, [0.0, 0.0, 1.0]))
                cone, delta = p.one("coneangle", 30.0), p.one("conedeltaangle", 5.0)
                if not 0.0 < cone < 180.0 or not 0.0 <= delta <= cone:
                    w.fail(line, f"{p.directive}: needs 0 < coneangle < 180 and 0 <= conedeltaangle <= coneangle, got "
                           f"{cone:g} and {delta:g}", "fix the angles")
                axis = m[:3, :3] @ (to - frm)
                if not np.linalg.norm(to - frm) > 0:
                    w.fail(line, f"{p.directive}: from equals to", "aim the spot at a point away from it")
                if not self._similarity(m):
                    w.fail(line, f"{p.directive}: a non-uniform scale or shear would make the cone elliptical",
                           "place the spot with rotations, translations and uniform scales")
                light.update(direction=axis / np.linalg.norm(axis), cone_angle=cone, falloff_start=cone - delta)
                cos_end, cos_start = math.cos(math.radians(cone)), math.cos(math.radians(cone - delta))
                k_e = 2.0 * math.pi * ((1.0 - cos_start) + (cos_start - cos_end) / 2.0)  # SpotLight::Create
            light["intensity"] = [scale * (power / k_e if power > 0 else 1.0) * v for v in rgb]
        elif kind == "distant":
            rgb = p.rgb("L", [1.0, 1.0, 1.0])
            e_v = p.one("illuminance", -1.0)
            frm = np.array(p.floats("from", ("point3",), 3, [0.0, 0.0, 0.0]))
            to = np.array(p.floats("to", ("point3",), 3, [0.0, 0.0, 1.0]))
            travel = m[:3, :3] @ (to - frm)
            if not np.linalg.norm(travel) > 0:
                w.fail(line, f"{p.directive}: from equals to", "give the direction the light travels, from -> to")
            light = {"type": "directional", "direction": travel / np.linalg.norm(travel),
                     "irradiance": [scale * (e_v if e_v > 0 else 1.0) * v for v in rgb]}  # DistantLight::Create
        elif kind == "infinite":
            light = self._infinite(p, w, line, scale, m)
        else:
            w.fail(line, f'LightSource "{kind}" is not read', 'use "point", "spot", "distant" or "infinite"')
        p.done()
        self.lights.append(light)

    def _infinite(self, p, w, line, scale, m) -> dict:
        """lights.cpp Light::Create "infinite": with "L" or nothing (UniformInfiniteLight) L (the illuminant's
        white: 1) x scale, with "illuminance" E_v > 0 x E_v / pi (the illuminance of L = 1 from above); with
        "filename" (ImageInfiniteLight) an equal-area octahedral map x scale, with "illuminance" x E_v / k_e,
        k_e pbrt-v4's sum (`_map_illuminance`), seen in the light's frame (the CTM's inverse, normalised:
        `_finish_environment`)."""
        if p.has("portal"):
            w.fail(line, f'{p.directive}: "point3 portal" (a portal light) is not read', "remove the portal (a constant "
                   '"rgb L" or a "filename" map without a portal is read)')
        e_v = p.one("illuminance", -1.0)
        if not p.has("filename"):
            rgb = p.rgb("L", [1.0, 1.0, 1.0])
            return {"type": "environment", "radiance": [scale * (e_v / math.pi if e_v > 0 else 1.0) * v for v in rgb]}
        if p.has("L"):
            w.fail(line, f'{p.directive}: both "L" and "filename"', 'give one (pbrt-v4 refuses both)')
        from ..output.film import read_exr

        path = self.resolve(p.string("filename"))
        if path.suffix.lower() != ".exr" or not path.is_file():
            w.fail(line, f'{p.directive}: "string filename": {path} is ' + ("not found" if not path.is_file() else
                   "not an OpenEXR file"), "give the map (pbrt-v4's equal-area octahedral square) as a linear RGB .exr")
        try:
            image = read_exr(path)[0]
        except UserError:
            w.fail(line, f"{p.directive}: {path} is not a readable RGB OpenEXR image", "give a linear RGB .exr file")
        if image.shape[0] != image.shape[1]:
            w.fail(line, f"{p.directive}: {path} is {image.shape[1]} x {image.shape[0]}: pbrt-v4's maps are square "
                   "(equal-area octahedral)", "give a square map")
        if not self._similarity(m):
            w.fail(line, f"{p.directive}: a non-uniform scale or shear would distort the map", "turn the light "
                   "with rotations (and uniform scales) alone")
        if e_v > 0:
            k_e = _map_illuminance(image)
            if not k_e > 0:
                w.fail(line, f'{p.directive}: "illuminance" of a map black above the horizon', "remove the "
                       "illuminance or give a map that lights the upper hemisphere")
            scale *= e_v / k_e
        inv = np.linalg.inv(m[:3, :3])
        return {"type": "environment", "map": str(path), "mapping": "octahedral", "scale": scale,
                "_to_light": inv / abs(np.linalg.det(inv)) ** (1.0 / 3.0)}

    @staticmethod
    def _similarity(m):
        g = m[:3, :3].T @ m[:3, :3]
        return np.allclose(g, np.eye(3) * g[0, 0], rtol=1e-9, atol=1e-12 * g[0, 0])

    def _Shape(self, kind, p, w, line):
        m = self._affine(w, line, p.directive)
        area = self.state.area  # the AreaLightSource of this attribute scope (`_AreaLightSource`), or None
        # scene.cpp getAlphaTexture: alpha < 1 is a stochastic alpha test; 0 lets every ray through
        alpha = p.one("alpha", 1.0)
        if alpha == 0.0 and area is None:
            p.params.clear()
            self.notes.append(f"{w.path}:{line}: {p.directive}: \"float alpha\" 0: invisible to every ray in pbrt; "
                              "left out")
            return
        if alpha not in (0.0, 1.0):
            w.fail(line, f'{p.directive}: "float alpha" {alpha:g} (a partly transparent surface) is not read',
                   "remove it (1, opaque) or set it to 0 (invisible)")
        if area is not None and self.state.material[0] == "interface":
            self.notes.append(f"{w.path}:{line}: {p.directive}: an area light on a shape with the \"interface\" "
                              "material: pbrt-v4 ignores the light (scene.cpp), so is it here")
            area = None
        if area is not None and alpha == 0.0:
            self.notes.append(f"{w.path}:{line}: {p.directive}: \"float alpha\" 0 with an area light: pbrt-v4 makes "
                              "it an invisible light (lights.cpp DiffuseAreaLight); read as an emitter that is seen "
                              "and occludes")
        # the emitting side (shapes.h: the surface normal, flipped by ReverseOrientation; a triangle's faces
        # its shading normals N where given): a mesh's winding is turned to it (emitters.oriented)
        flip = self.state.reverse ^ (np.linalg.det(m[:3, :3]) < 0.0)
        if kind == "sphere":
            r = p.one("radius", 1.0)
            if not r > 0.0:
                w.fail(line, f"{p.directive}: radius {r:g} must be positive", "use a radius > 0")
            for k in ("zmin", "zmax", "phimax"):
                if p.has(k):
                    w.fail(line, f'{p.directive}: "{k}" (a partial sphere) is not read', "remove it (a whole sphere)")
            p.done()
            if self._similarity(m):
                shape = {"primitive": "sphere", "center": m[:3, 3], "radius": r * math.sqrt((m[:3, 0] @ m[:3, 0])),
                         "segments": SPHERE_SEGMENTS, "exact": True}
                if area is not None:
                    if self.state.reverse:
                        w.fail(line, f"{p.directive}: an area light on a sphere under ReverseOrientation emits "
                               "inward, which is not read", "remove ReverseOrientation")
                    # a sphere emits outward (twosided: also inward, unseen from outside)
                    self._area_light({"type": "sphere", "center": shape["center"], "radius": shape["radius"]},
                                     area, [4.0 * math.pi * r * r], w, line)  # Sphere::Area: object space
                    return
            else:
                if area is not None:
                    w.fail(line, f"{p.directive}: an area light on a sphere scaled unevenly (an ellipsoid) is not "
                           "read", "scale it uniformly")
                from ..scene.meshes import sphere_triangles
                shape = _triangles(sphere_triangles(np.zeros(3), r, SPHERE_SEGMENTS) @ m[:3, :3].T + m[:3, 3])
        elif kind == "disk":
            h, r = p.one("height", 0.0), p.one("radius", 1.0)
            if not r > 0.0 or p.one("innerradius", 0.0) != 0.0 or p.one("phimax", 360.0) != 360.0:
                w.fail(line, f"{p.directive}: only a whole disk (radius > 0, innerradius 0, phimax 360) is read",
                       "remove innerradius and phimax")
            p.done()
            x, y = m[:3, 0], m[:3, 1]
            centre = m[:3, :3] @ [0.0, 0.0, h] + m[:3, 3]
            if area is not None:
                if not math.isclose(x @ x, y @ y, rel_tol=1e-9) or abs(x @ y) > 1e-9 * (x @ x):
                    w.fail(line, f"{p.directive}: an area light on a disk stretched into an ellipse is not read",
                           "scale the disk uniformly in its plane")
                n = np.linalg.inv(m[:3, :3]).T @ [0.0, 0.0, 1.0]  # Disk: +z as a normal, flipped by ReverseOrientation
                n = (-1.0 if self.state.reverse else 1.0) * n / np.linalg.norm(n)
                self._area_light({"type": "disk", "center": centre, "normal": n, "radius": r * math.sqrt(x @ x)},
                                 area, [math.pi * r * r], w, line)  # Disk::Area: object space
                return
            ang = np.linspace(0.0, 2.0 * math.pi, SPHERE_SEGMENTS + 1)
            ring = r * np.stack([np.cos(ang), np.sin(ang), np.full_like(ang, h)], axis=1)
            fan = np.stack([np.broadcast_to([0.0, 0.0, h], (SPHERE_SEGMENTS, 3)), ring[:-1], ring[1:]], axis=1)
            shape = _triangles(fan @ m[:3, :3].T + m[:3, 3])
        elif kind in ("trianglemesh", "bilinearmesh"):
            pts = np.array(p.floats("P", ("point3",)) or [], float).reshape(-1, 3)
            per = 3 if kind == "trianglemesh" else 4
            idx = p.ints("indices")
            if idx is None:
                if len(pts) != per:
                    w.fail(line, f'{p.directive}: "integer indices" missing', f"give them ({per} per "
                           f"{'triangle' if per == 3 else 'patch'}), or exactly {per} points")
                idx = list(range(per))
            idx = np.array(idx, dtype=np.int64)
            if len(pts) == 0 or idx.size == 0 or idx.size % per or idx.min() < 0 or idx.max() >= len(pts):
                w.fail(line, f'{p.directive}: needs points "P" and {per} indices per element into them',
                       f"check the counts (P has {counted(len(pts), 'point')})")
            normals = np.array(p.floats("N", ("normal", "normal3")) or [], float).reshape(-1, 3) if per == 3 else []
            p.ignore("uv", "N", "S", "faceIndices")  # a bilinear patch's N: its triangles are flat
            p.done()
            pts = pts @ m[:3, :3].T + m[:3, 3]
            if per == 3:
                shape = {"primitive": "triangles", "vertices": pts, "faces": idx.reshape(-1, 3)}
                if len(normals) == len(pts):  # per-vertex shading normals: smooth (by the inverse transpose)
                    shape["normals"] = normals @ np.linalg.inv(m[:3, :3])
            else:
                patches = [pts[q] for q in idx.reshape(-1, 4)]
                if area is not None and len(patches) == 1 and _parallelogram(patches[0]):
                    c = patches[0][[0, 1, 3, 2]]  # p00 p10 p11 p01: normal dpdu x dpdv, as pbrt's
                    self._area_light({"type": "quad", "corners": c[[0, 3, 2, 1]] if flip else c}, area,
                                     [float(np.linalg.norm(np.cross(c[1] - c[0], c[3] - c[0])))], w, line)
                    return
                grids = [_patch(q) for q in patches]
                shape = _triangles(np.concatenate(grids))
                if area is not None:  # BilinearPatch::Area, per patch (`_emitting`)
                    shape["_areas"] = [(len(g), float(_area(g).sum())) for g in grids]
        elif kind == "loopsubdiv":
            pts = np.array(p.floats("P", ("point3",)) or [], float).reshape(-1, 3)
            idx = np.array(p.ints("indices") or [], dtype=np.int64)
            levels = int(p.one("levels", 3, ("integer",)))
            if len(pts) == 0 or idx.size == 0 or idx.size % 3 or idx.min() < 0 or idx.max() >= len(pts):
                w.fail(line, f'{p.directive}: needs points "P" and 3 "integer indices" per triangle into them',
                       f"check the counts (P has {counted(len(pts), 'point')})")
            if not 0 <= levels or idx.size // 3 * 4 ** levels > MAX_SUBDIVIDED:
                w.fail(line, f'{p.directive}: "integer levels" {levels} would make {idx.size // 3} x 4^{levels} '
                       "triangles", f"give 0 to {_most_levels(idx.size // 3)} levels")
            p.done()
            try:
                v, f, vn = loop.surface(pts, idx.reshape(-1, 3), levels)
            except loop.NotManifold as exc:
                w.fail(line, f"{p.directive}: the control mesh is not a consistently wound manifold ({exc}), which "
                       "Loop subdivision needs", 'fix the mesh, or read it as a "trianglemesh"')
            shape = {"primitive": "triangles", "vertices": v @ m[:3, :3].T + m[:3, 3], "faces": f,
                     "normals": vn @ np.linalg.inv(m[:3, :3])}
        elif kind == "plymesh":
            name = p.string("filename")
            if name is None:
                w.fail(line, f'{p.directive}: no "string filename"', 'add "string filename" "mesh.ply"')
            p.done()
            v, f, vn = _read_ply(self.resolve(name), w, line)
            shape = {"primitive": "triangles", "vertices": v @ m[:3, :3].T + m[:3, 3], "faces": f}
            if vn is not None:  # the PLY's nx ny nz: pbrt's N
                shape["normals"] = vn @ np.linalg.inv(m[:3, :3])
        else:
            w.fail(line, f'Shape "{kind}" is not read', 'use "trianglemesh", "plymesh", "sphere", "disk", '
                   '"bilinearmesh" or "loopsubdiv"')
        if area is not None:
            shape = self._emitting(shape, area, flip, w, line)
        shape["_material"], shape["_media"], shape["_where"] = self.state.material, (self.state.inside,
                                                                                      self.state.outside), (w, line)
        self.shapes.append(shape)

    def _area_light(self, light, area, areas, w, line):
        """A quad, disk or sphere light of the area light in scope (its radiance for the shape's area)."""
        light["radiance"] = _radiance(area, areas[0])
        if area["twosided"] and light["type"] != "sphere":
            light["two_sided"] = True
        self.lights.append(light)

    def _emitting(self, shape, area, flip, w, line) -> dict:
        """A triangle mesh with the area light in scope: faces wound towards pbrt's emitting side, its
        `emission` (pbrt-v4 gives each triangle or patch its own light: with "power", one of that power
        each, so elements of different areas become shapes of their own, `_areas`)."""
        faces = np.asarray(shape["faces"])
        if "normals" in shape:
            faces = emitters.oriented(faces, shape["vertices"], shape["normals"])
        elif flip:
            faces = faces[:, ::-1]
        shape["faces"] = faces
        # (triangles, area) of each element: a triangle, or a patch's triangles (BilinearPatch::Area)
        elements = shape.pop("_areas", None) or [(1, a) for a in _area(np.asarray(shape["vertices"])[faces])]
        areas = [a for _, a in elements]
        if area["twosided"]:
            shape["two_sided"] = True
        if area["power"] <= 0.0 or np.allclose(areas, areas[0], rtol=1e-12, atol=0.0):
            shape["emission"] = _radiance(area, areas[0])
            return shape
        if len(elements) > MAX_POWER_PARTS:
            w.fail(line, f'AreaLightSource "diffuse": "power" on a mesh of {len(elements)} elements of different '
                   f"areas (pbrt-v4 gives each its own light of that power) is read for at most {MAX_POWER_PARTS}",
                   'give "rgb L" instead of "power"')
        ends = np.cumsum([0] + [n for n, _ in elements])
        parts = [{**shape, "faces": faces[a:b], "emission": _radiance(area, e)} for a, b, e in zip(ends, ends[1:], areas)]
        for part in parts[:-1]:
            part["_material"], part["_media"], part["_where"] = self.state.material, (self.state.inside,
                                                                                       self.state.outside), (w, line)
            self.shapes.append(part)
        return parts[-1]

    def _AreaLightSource(self, kind, p, w, line):
        """lights.cpp DiffuseAreaLight::Create: L (the illuminant's white: 1) x scale, and with "power" P > 0
        x P / k_e, k_e = (2 if twosided else 1) pi A for each shape's own area A (`_radiance`)."""
        if kind != "diffuse":
            w.fail(line, f'AreaLightSource "{kind}" is not read', 'use "diffuse"')
        if p.has("filename"):
            w.fail(line, f'{p.directive}: "string filename" (an image on the emitter) is not read',
                   'give a constant "rgb L"')
        area = {"L": np.array(p.rgb("L", [1.0, 1.0, 1.0])) * p.one("scale", 1.0), "twosided": p.boolean("twosided"),
                "power": p.one("power", -1.0)}
        p.done()
        self.state.area = area

    # --- the scene dict
    def scene(self) -> dict:
        """The scene dict; a shape that cannot be read is recorded in `problems` and left out."""
        if self.stack:
            _, line, path = self.stack[-1]
            with self.problems.each():
                raise UserError(f"{path}:{line}: AttributeBegin without AttributeEnd; close it")
        if self.camera is None:
            if self.problems.items:  # the Camera was refused: listed
                return {}
            raise UserError(f'{self.main}: no Camera; add LookAt ... and Camera "perspective" before WorldBegin')
        out = {"name": self.main.stem.removesuffix(".pbrt"), "shape": [], "light": []}
        s, camera_medium = np.ones(3), None  # stand-ins while the camera is refused: shapes are read on
        with self.problems.each():
            out["camera"], s, camera_medium = self._camera()
        if camera_medium is not None and (any(camera_medium["sigma_a"]) or any(camera_medium["sigma_s"])):
            out["medium"] = camera_medium
        ratio = self.exposure * self.iso / 100.0  # film.cpp: imagingRatio
        if ratio != 1.0:
            self.notes.append(f"{self.main}: Film: pbrt-v4 scales the image by exposure time x iso / 100 = "
                              f"{self.exposure:g} x {self.iso:g} / 100 = {ratio:g} (film.cpp imagingRatio); the lights' "
                              "power is scaled by it instead (the same image: it is linear in the lights)")
        mirrored = s[0] < 0.0  # (a mirror turns windings: quads and faces are turned back)
        for light in self.lights:
            light = _finish_environment(dict(light), s, ratio)
            for k in ("intensity", "irradiance", "radiance"):
                if k in light:
                    light[k] = [ratio * v for v in light[k]]
            for k in ("position", "direction", "center", "normal", "corners"):
                if k in light:
                    light[k] = np.asarray(light[k]) * s + 0.0
            if mirrored and "corners" in light:
                light["corners"] = light["corners"][[0, 3, 2, 1]]
            out["light"].append(light)
        for shape in self.shapes:
            with self.problems.each():
                shape = self._surface(dict(shape), self.camera[3], camera_medium)
                if shape is not None:
                    for k in ("vertices", "center", "normals"):
                        if k in shape:
                            shape[k] = shape[k] * s + 0.0
                    if mirrored and "faces" in shape:
                        shape["faces"] = np.asarray(shape["faces"])[:, ::-1]
                    if "emission" in shape:
                        shape["emission"] = [ratio * v for v in shape["emission"]]
                    out["shape"].append(shape)
        return _plain(out)

    def _camera(self):
        """(our camera, the world's x factors (-1 in x: mirrored), the camera's medium)."""
        kind, wfc, fov, medium, cpath, cline = self.camera
        camera_medium = self._medium(medium, _Where(cpath), cline)
        lin = wfc[:3, :3]
        x, y, z = (lin[:, k] / np.linalg.norm(lin[:, k]) for k in range(3))
        # exporters write rotations with a few decimals (Houdini's: 4, axes off by ~1e-4): orthonormal to a
        # relative ORTHO_REFUSE is read with its view direction and up, a note above ORTHO_NOTE
        norms = [np.linalg.norm(lin[:, k]) for k in range(3)]
        off = max(abs(x @ y), abs(y @ z), abs(x @ z), (max(norms) - min(norms)) / max(norms))
        if off > ORTHO_REFUSE:
            raise UserError(f"{cpath}:{cline}: Camera: its transform scales unevenly or shears the image (axes off "
                            f"orthonormal by {off:.2g}); place the camera with LookAt, rotations and translations")
        if off > ORTHO_NOTE:
            self.notes.append(f"{cpath}:{cline}: Camera: its transform is orthonormal to {off:.2g} (a rotation written "
                              "with few decimals); read with its view direction and its up made orthogonal to it")
        # pbrt's perspective raster x runs along camera x, ours along forward x up: mirrored when det > 0
        # (a plain LookAt); its equirectangular image matches ours when det > 0 (cameras.cpp GenerateRay)
        det = np.linalg.det(lin)
        mirror = det > 0 if kind == "perspective" else det < 0
        s = np.array([-1.0, 1.0, 1.0]) if mirror else np.ones(3)  # (+ 0.0 below: no -0.0 in the dict)
        pos = wfc[:3, 3] * s + 0.0
        forward = (z if kind == "perspective" else -x) * s
        W, H = self.film
        cam = {"type": "perspective" if kind == "perspective" else "environment", "position": pos,
               "look_at": pos + forward, "up": y * s + 0.0, "width": W, "height": H, "spp": self.spp}
        if kind == "perspective":
            cam["fov"] = self._vertical_fov(fov, W, H, _Where(cpath), cline)
        return cam, s, camera_medium

    def _vertical_fov(self, fov, W, H, w, line) -> float:
        """Our vertical fov from pbrt's `fov` and screen window (cameras.cpp PerspectiveCamera::Create and
        CameraBase: the window [x0, x1] x [y0, y1] on the plane where tan(fov / 2) = 1 spans the image)."""
        window, frame = self.screen
        frame = W / H if frame is None else frame
        x0, x1, y0, y1 = window or ([-frame, frame, -1.0, 1.0] if frame > 1.0 else [-1.0, 1.0, -1.0 / frame, 1.0 / frame])
        key = '"float screenwindow"' if window else '"float frameaspectratio"'
        if not (x1 > x0 and y1 > y0):
            w.fail(line, f"Camera: {key} [{x0:g} {x1:g} {y0:g} {y1:g}] is empty or flipped", "give x0 < x1 and y0 < y1")
        size = max(x1 - x0, y1 - y0)
        if abs(x0 + x1) > 1e-6 * size or abs(y0 + y1) > 1e-6 * size:
            w.fail(line, f"Camera: {key} [{x0:g} {x1:g} {y0:g} {y1:g}] is off-centre (a lens shift), which is not read",
                   "use a window symmetric about 0 (ours looks through the image centre)")
        if abs((x1 - x0) / (y1 - y0) - W / H) > 1e-3 * W / H:
            w.fail(line, f"Camera: {key}: the window's aspect {(x1 - x0) / (y1 - y0):.6g} differs from the film's "
                   f"{W}/{H} = {W / H:.6g}, so pbrt stretches the image (non-square pixels), which is not read",
                   f"give the window the film's aspect, e.g. [-{x1:g} {x1:g} -{x1 * H / W:.6g} {x1 * H / W:.6g}]")
        return math.degrees(2.0 * math.atan(y1 * math.tan(math.radians(fov) / 2.0)))

    def _medium(self, name, w, line):
        if name == "":
            return None
        if name not in self.media:
            w.fail(line, f'medium "{name}" is not defined', f'define it with MakeNamedMedium "{name}" ...')
        return self.media[name][0] or {"sigma_a": [0.0] * 3, "sigma_s": [0.0] * 3}  # (a refused medium: listed)

    def _surface(self, shape, camera_name, camera_medium):
        """The shape's reflectance or interior from its material and medium interface (pbrt: a shape whose
        inside and outside media differ bounds a medium; an "interface" material is invisible)."""
        mat = shape.pop("_material")
        inside, outside = shape.pop("_media")
        w, line = shape.pop("_where")
        transition = inside != outside
        if transition and outside != camera_name:
            w.fail(line, f'Shape: its outside medium "{outside}" is not the camera\'s "{camera_name}"',
                   "our scenes have one surrounding medium: give the shape MediumInterface \"inner\" \"" + camera_name
                   + '"')
        inner = self._medium(inside, w, line) if transition else camera_medium
        if mat[0] == "diffuse":
            shape["reflectance"] = mat[1]  # opaque: a medium inside it is never reached
            return shape
        if mat[0] == "interface" and not transition:
            return None  # pbrt skips it: it changes nothing
        medium = inner or {"sigma_a": [0.0] * 3, "sigma_s": [0.0] * 3, "phase": "isotropic"}
        shape["interior"] = {**medium, "ior": 1.0 if mat[0] == "interface" else mat[1]}
        return shape


def _patch(q):
    """A bilinear patch (p00, p10, p01, p11) as triangles: two if planar, else a PATCH_GRID^2 grid."""
    p00, p10, p01, p11 = q
    size = max(np.ptp(q, axis=0).max(), 1e-300)
    planar = abs(np.cross(p10 - p00, p01 - p00) @ (p11 - p00)) <= 1e-9 * size ** 3
    n = 1 if planar else PATCH_GRID
    t = np.linspace(0.0, 1.0, n + 1)
    u, v = np.meshgrid(t, t, indexing="ij")
    g = ((1 - u) * (1 - v))[..., None] * p00 + (u * (1 - v))[..., None] * p10 + ((1 - u) * v)[..., None] * p01 \
        + (u * v)[..., None] * p11
    a, b, c, d = g[:-1, :-1], g[1:, :-1], g[1:, 1:], g[:-1, 1:]
    return np.concatenate([np.stack([a, b, c], -2).reshape(-1, 3, 3), np.stack([a, c, d], -2).reshape(-1, 3, 3)])


def _parallelogram(q) -> bool:
    """Whether a bilinear patch (p00, p10, p01, p11) is a parallelogram of non-zero area (a quad light)."""
    p00, p10, p01, p11 = q
    size = max(float(np.abs(q).max()), 1e-300)
    return bool(np.allclose(p00 + p11, p10 + p01, rtol=0.0, atol=1e-12 * size)
                and np.linalg.norm(np.cross(p10 - p00, p01 - p00)) > 0.0)


def _area(tris) -> np.ndarray:
    """Each triangle's area (T,)."""
    return 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)


def _map_illuminance(image) -> float:
    """pbrt-v4's k_e for "illuminance" with a map (lights.cpp Light::Create "infinite"): 2 pi / N^2 x the sum
    over the texels whose centre has z > 0 of luminance x z. The texels' solid angle is 4 pi / N^2, so k_e
    is half the upper hemisphere's illuminance (pi / 2 for L = 1): pbrt-v4 scales a map to twice the
    illuminance it is given, and so do we, to render as pbrt-v4 does."""
    from ..lights import environment, octahedral

    n = image.shape[0]
    c = (np.arange(n) + 0.5) / n
    z = octahedral.square_to_sphere(*np.meshgrid(c, c))[..., 2]  # rows: v, columns: u
    return float(2.0 * np.pi / (n * n) * np.sum(np.where(z > 0.0, (image @ environment.LUMA) * z, 0.0)))


def _finish_environment(light: dict, s, ratio) -> dict:
    """An octahedral map's `rotate` (and `mirror`) once the world's x factors `s` are known: pbrt looks up
    normalize(M^-1 w_pbrt), ours TO_PBRT R^T w with w = s w_pbrt, so R = diag(s) (M^-1 / c)^T TO_PBRT;
    the image's `scale` x the film's `ratio`."""
    if "_to_light" not in light:
        return light
    from ..lights import environment, octahedral

    light.update(environment.rotate_keys(np.diag(s) @ light.pop("_to_light").T @ octahedral.TO_PBRT))
    light["scale"] *= ratio
    return light


def _radiance(area: dict, size: float) -> list[float]:
    """The radiance of an area light (`_Reader._AreaLightSource`) on a shape of area `size`."""
    power = area["power"]
    k_e = (2.0 if area["twosided"] else 1.0) * math.pi * size
    return (area["L"] * (power / k_e if power > 0.0 else 1.0)).tolist()


def _most_levels(faces: int) -> int:
    """The most Loop subdivision levels of `faces` triangles within MAX_SUBDIVIDED."""
    return max(0, int(math.log(MAX_SUBDIVIDED / faces, 4)))


def _triangles(tris):
    """An inline mesh from a triangle soup (T, 3, 3), shared corners merged."""
    v, f = np.unique(tris.reshape(-1, 3), axis=0, return_inverse=True)
    return {"primitive": "triangles", "vertices": v, "faces": f.reshape(-1, 3)}


def _read_ply(path: Path, w: _Where, line: int):
    if not path.is_file():
        w.fail(line, f'plymesh: file "{path}" not found', "check the file name (relative to the main pbrt file)")
    try:
        data = path.read_bytes()
        if path.suffix == ".gz":
            data = gzip.decompress(data)
        v, f, vn = read_mesh(_io.BytesIO(data), "ply")
    except Exception as exc:  # trimesh raises many types for unreadable files
        w.fail(line, f'plymesh: cannot read "{path}" ({type(exc).__name__}: {exc})', "write it as a PLY mesh")
    if len(f) == 0 or not np.all(np.isfinite(v)):
        w.fail(line, f'plymesh: "{path}" has no faces or non-finite vertices', "fix the mesh")
    return v, f, vn


def _plain(x):
    """numpy arrays and scalars as plain lists and floats (the scene dict is TOML's structure)."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return x


def read_scene(path: Path) -> dict:
    """The scene dict of a pbrt-v4 file, or UserError naming the file, the line and the fix."""
    problems = Problems(str(path))
    reader = _Reader(Path(path), problems)
    try:
        reader.run(Path(path))
        out = reader.scene()
    except UserError as exc:  # malformed input, a missing include: reading stops there
        problems.check(fatal=exc)
    problems.check()
    for note in reader.notes:
        warnings.warn(note, PbrtNote, stacklevel=2)
    return out


# --------------------------------------------------------------------------------------------- writing


def _f(x) -> str:
    return repr(float(x))


def _list(values) -> str:
    return "[ " + " ".join(_f(v) if not isinstance(v, (int, np.integer)) else str(int(v)) for v in values) + " ]"


def _refuse(source, key, what, approximate, closest):
    """Refuse what pbrt cannot express, or (with --approximate) warn and write `closest`."""
    if not approximate:
        raise UserError(f"{source}: {key}: {what}; change it, or pass --approximate to write {closest}")
    print(f"warning: {source}: {key}: {what}; written as {closest}", file=sys.stderr)


def _phase_g(phase, key, source, approximate) -> float:
    if phase == "rayleigh" or isinstance(phase, dict) and phase.get("type") == "rayleigh":
        _refuse(source, key, "pbrt-v4's homogeneous medium has no Rayleigh phase function", approximate,
                "isotropic (the same mean cosine, 0)")
        return 0.0
    g = float(phase.get("g", 0.0)) if isinstance(phase, dict) else 0.0
    if abs(g) > HG_MAX:
        _refuse(source, f"{key}.g", f"pbrt-v4 clamps Henyey-Greenstein's g to +-{HG_MAX}", approximate,
                f"g = {math.copysign(HG_MAX, g)}")
        return math.copysign(HG_MAX, g)
    return g


def _medium_line(name, sa, ss, g) -> str:
    return (f'MakeNamedMedium "{name}" "string type" "homogeneous" "rgb sigma_a" {_list(sa)} "rgb sigma_s" '
            f'{_list(ss)} "float scale" [ 1.0 ] "float g" [ {_f(g)} ]')


def _ply_bytes(vertices, faces, normals=None) -> bytes:
    """A binary PLY: double vertices (and normals nx ny nz, pbrt's "N", when given), int faces."""
    extra = "property double nx\nproperty double ny\nproperty double nz\n" if normals is not None else ""
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\nproperty double x\n"
            f"property double y\nproperty double z\n{extra}element face {len(faces)}\n"
            "property list uchar int vertex_indices\nend_header\n").encode()
    rows = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", 3)])
    rows["n"], rows["i"] = 3, faces
    table = vertices if normals is None else np.concatenate([vertices, normals], axis=1)
    return head + np.ascontiguousarray(table, dtype="<f8").tobytes() + rows.tobytes()


def _groups(tris, refl):
    """(vertices, faces, reflectance) per distinct reflectance of one shape's triangles, corners merged."""
    keys, inverse = np.unique(refl, axis=0, return_inverse=True)
    for k, r in enumerate(keys):
        mesh = _triangles(tris[inverse.ravel() == k])
        yield mesh["vertices"], mesh["faces"], r


def export(raw: dict, out: Path, source: str, approximate: bool) -> list[Path]:
    """Write the scene dict as a pbrt-v4 file for `volpath` at maxdepth 1 (single scattering: integrators.cpp
    stops a path at its second scattering event), meshes of mesh files as PLY beside it; returns the files."""
    from ..camera import basis
    from ..scene.format import scene_from_dict
    from ..scene.meshes import scene_triangles, world_sphere

    raw, area_lights, emission = emitters.split(raw)
    for i, light in enumerate(raw.get("light", [])):
        if light.get("falloff", "smoothstep") != "smoothstep":
            _refuse(source, f"light[{i}].falloff", f'pbrt-v4\'s spot has only the smoothstep falloff, not '
                    f'"{light["falloff"]}"', approximate, "a smoothstep spot with the same angles")
        light.pop("falloff", None)
    medium = raw.get("medium", {})
    path = Path(source) if Path(source).is_file() else None
    scene = scene_from_dict(raw, source, path)
    if not scene.medium.homogeneous:
        raise UserError(f"{source}: medium.type: pbrt-v4 cannot express a {scene.medium.type_name} medium (its media "
                        "are homogeneous or voxel grids); export a scene with a homogeneous medium")
    if "particles" in medium:
        _refuse(source, "medium.particles", "pbrt-v4 has no particle layer", approximate, "the air-light alone")
    cam = scene.camera
    stem = out.name.removesuffix(".pbrt")
    lines = [f"# pbrt-v4 scene written by raytrace-media from {source}",
             "# single scattering: volpath stops a path at its second scattering event with maxdepth 1",
             'Integrator "volpath" "integer maxdepth" [ 1 ]',
             f'Sampler "independent" "integer pixelsamples" [ {cam.spp} ]',
             'PixelFilter "box" "float xradius" [ 0.5 ] "float yradius" [ 0.5 ]',
             f'Film "rgb" "integer xresolution" [ {cam.width} ] "integer yresolution" [ {cam.height} ] '
             f'"string filename" [ "{stem}.exr" ]']
    fog = bool(np.any(scene.medium.sigma_t > 0))
    outside = "fog" if fog else ""
    if fog:
        lines.append(_medium_line("fog", scene.medium.sigma_a, scene.medium.sigma_s,
                                  _phase_g(medium.get("phase", "isotropic"), "medium.phase", source, approximate)))
        lines.append('MediumInterface "fog" "fog"  # the camera\'s medium (and every shape\'s outside)')
    forward, right, up = basis(cam)
    if cam.type == "perspective":
        # pbrt's raster x runs along up x dir; Scale -1 1 1 turns it into our right = dir x up
        fov = cam.fov if cam.width > cam.height else \
            math.degrees(2.0 * math.atan(math.tan(math.radians(cam.fov) / 2.0) * cam.width / cam.height))
        lines += ["Scale -1 1 1", f"LookAt {' '.join(map(_f, cam.position))}  {' '.join(map(_f, cam.look_at))}  "
                  f"{' '.join(map(_f, cam.up))}", f'Camera "perspective" "float fov" [ {_f(fov)} ]']
    else:
        # pbrt's equirectangular image is centred on camera -x with camera -z to its right
        lines += [f"LookAt {' '.join(map(_f, cam.position))}  {' '.join(map(_f, cam.position - right))}  "
                  f"{' '.join(map(_f, up))}", 'Camera "spherical" "string mapping" "equirectangular"']
    lines.append("WorldBegin")
    lines += [_light_line(light, lraw) for light, lraw in zip(scene.lights, raw.get("light", []))]
    for i, light in area_lights:
        lines += _area_light_lines(light, f"light[{i}]", source, path)
    files = {}
    tris, refl, ids, corners = scene_triangles(scene, shape_ids=True, normals=True)
    for i, shape in enumerate(scene.shapes):
        mine = ids == i
        lines.append("AttributeBegin")
        # a sphere goes out as pbrt's where it reads back the same: exact (also holding a medium, or emitting:
        # read back as the sphere light it is); a mesh of a sphere goes out as its triangles
        sphere = world_sphere(shape) if shape.kind == "sphere" and shape.params["exact"] else None
        if i in emission:  # emitting towards each triangle's winding (or its N: oriented to the winding)
            if shape.interior is not None:
                raise UserError(f"{source}: shape[{i}].emission: an emitting shape that holds a medium cannot be "
                                "exported; put the medium in a shape of its own")
            lines.append(_area_line(*emitters.emission_of(emission[i], f"shape[{i}]", source)))
        if shape.interior is not None:
            it = shape.interior
            if it.ior != 1.0:
                _refuse(source, f"shape[{i}].interior.ior", "volpath cannot light a medium behind a refracting "
                        "(delta) boundary: its shadow rays stop there", approximate, "an index-matched interface")
            g = _phase_g(raw["shape"][i]["interior"].get("phase", "isotropic"), f"shape[{i}].interior.phase", source,
                         approximate)
            lines += [_medium_line(f"interior{i}", it.sigma_a, it.sigma_s, g),
                      f'MediumInterface "interior{i}" "{outside}"', 'Material "interface"']
            mesh = _triangles(tris[mine])
            groups = [(mesh["vertices"], mesh["faces"], None)]
        else:
            groups = list(_groups(tris[mine], refl[mine]))
        if sphere is not None:  # written back as pbrt's sphere (read as an exact one, `_Reader` above)
            if shape.interior is None:
                lines.append(f'Material "diffuse" "rgb reflectance" {_list(groups[0][2])}')
            lines += [f"Translate {' '.join(map(_f, sphere[0]))}", f'Shape "sphere" "float radius" [ {_f(sphere[1])} ]',
                      "AttributeEnd"]
            continue
        for k, (v, f, r) in enumerate(groups):
            if r is not None:
                lines.append(f'Material "diffuse" "rgb reflectance" {_list(r)}')
            sel = np.nonzero(mine)[0] if r is None else np.nonzero(mine & np.all(refl == r, axis=1))[0]
            if shape.kind == "mesh":
                name = f"{stem}_shape{i}" + (f"_{k}" if len(groups) > 1 else "") + ".ply"
                if corners is not None and shape.smooth:  # the mesh's shading normals as the PLY's nx ny nz
                    rows, f = np.unique(np.concatenate([tris[sel], corners[sel]], axis=2).reshape(-1, 6), axis=0,
                                        return_inverse=True)
                    files[out.parent / name] = _ply_bytes(rows[:, :3], f.reshape(-1, 3), rows[:, 3:])
                else:
                    files[out.parent / name] = _ply_bytes(v, f)
                lines.append(f'Shape "plymesh" "string filename" [ "{name}" ]')
            elif corners is not None and shape.smooth:  # corner by corner, with pbrt's shading normals "N"
                lines.append(f'Shape "trianglemesh" "point3 P" {_list(tris[sel].ravel())} "integer indices" '
                             f'{_list(np.arange(3 * len(sel)))} "normal N" {_list(corners[sel].ravel())}')
            else:
                lines.append(f'Shape "trianglemesh" "point3 P" {_list(v.ravel())} "integer indices" {_list(f.ravel())}')
        lines.append("AttributeEnd")
    if np.any(scene.background > 0):
        _refuse(source, "background.radiance", "pbrt's constant environment light would also light the scene",
                approximate, "a black background")
    files[out] = ("\n".join(lines) + "\n").encode()
    written = []
    try:
        for p, data in files.items():
            p.write_bytes(data)
            written.append(p)
    except OSError as exc:
        for p in written:
            p.unlink(missing_ok=True)
        raise UserError(f"{out}: cannot write ({exc}); choose a writable --out") from None
    return list(files)


def _area_line(radiance, two_sided) -> str:
    """An AreaLightSource of this radiance (no "power", "scale" 1: L is the radiance, `_radiance`)."""
    return f'AreaLightSource "diffuse" "rgb L" {_list(radiance)}' + (' "bool twosided" true' if two_sided else "")


def _area_light_lines(light, key, source, path=None) -> list[str]:
    """A quad, disk or sphere light as a black emitting bilinear patch, disk or sphere (the inverse of
    `_Reader._Shape`), or the environment as an infinite light (`_environment_lines`)."""
    kind = light.get("type")
    if kind == "environment":
        return _environment_lines(light, key, source, path)
    radiance = emitters.colour(light.get("radiance"), f"{key}.radiance", source)
    two = light.get("two_sided", False)
    lines = ["AttributeBegin", _area_line(radiance, two is True), 'Material "diffuse" "rgb reflectance" [ 0 0 0 ]']
    if kind == "quad":
        c = emitters.vector(light.get("corners"), f"{key}.corners", source, rows=4)
        emitters.quad_frame(c, f"{key}.corners", source)
        lines.append(f'Shape "bilinearmesh" "point3 P" {_list(c[[0, 1, 3, 2]].ravel())}')  # p00 p10 p01 p11
    elif kind == "disk":
        m, r = emitters.disk_frame(light, key, source)  # a rotation: no handedness swap
        lines += [f"ConcatTransform {_list(m.T.ravel())}", f'Shape "disk" "float radius" [ {_f(r)} ]']
    else:
        c = emitters.vector(light.get("center"), f"{key}.center", source)
        r = emitters.positive(light.get("radius"), f"{key}.radius", source)
        lines += [f"Translate {' '.join(map(_f, c))}", f'Shape "sphere" "float radius" [ {_f(r)} ]']
    return lines + ["AttributeEnd"]


def _environment_lines(light, key, source, path) -> list[str]:
    """A constant environment as an "rgb L" infinite light; an octahedral map as a "filename" one under
    the ConcatTransform M = R TO_PBRT^T (the inverse of `_finish_environment`: our world is pbrt's here)
    with its "scale". An equirectangular map is refused: pbrt-v4 reads octahedral maps only, and
    resampling one into the other is not exact."""
    if "map" not in light:
        return [f'LightSource "infinite" "rgb L" {_list(emitters.constant_environment(light, key, source))}']
    if light.get("mapping", "equirectangular") != "octahedral":
        raise UserError(f"{source}: {key}.map: pbrt-v4's environment maps are equal-area octahedral squares and "
                        "this exporter does not resample an equirectangular map (not exactly); export a constant "
                        "environment (radiance), an octahedral map, or use Mitsuba")
    from ..lights import environment, octahedral
    from ..scene.assets import find_asset
    from ..scene.meshes import rotation_matrix

    file = find_asset(str(light["map"]), path, f"{key}.map", "environment map")  # as the reader finds it
    scale = emitters.constant_environment({"radiance": 1.0, "scale": light.get("scale", 1.0)}, key, source)[0]
    m = np.eye(4)
    m[:3, :3] = rotation_matrix(emitters.vector(light.get("rotate", [0.0, 0.0, 0.0]), f"{key}.rotate", source)) @ \
        (environment.MIRROR if light.get("mirror") is True else np.eye(3)) @ octahedral.TO_PBRT.T
    return ["AttributeBegin", f"ConcatTransform {_list(m.T.ravel())}",
            f'LightSource "infinite" "string filename" [ "{file.resolve()}" ] "float scale" [ {_f(scale)} ]',
            "AttributeEnd"]


def _light_line(light, lraw) -> str:
    from ..lights import DIRECTIONAL, SPOT

    if light.kind == DIRECTIONAL:
        return (f'LightSource "distant" "point3 from" [ 0.0 0.0 0.0 ] "point3 to" {_list(light.axis)} '
                f'"rgb L" {_list(light.intensity)}')
    pos = light.position
    if light.kind != SPOT:
        return f'LightSource "point" "point3 from" {_list(pos)} "rgb I" {_list(light.intensity)}'
    to = np.asarray(lraw["look_at"], float) if "look_at" in lraw else pos + light.axis
    cone = float(lraw.get("cone_angle", 30.0))
    start = float(lraw.get("falloff_start", max(cone - 5.0, 0.0)))
    return (f'LightSource "spot" "point3 from" {_list(pos)} "point3 to" {_list(to)} "float coneangle" [ {_f(cone)} ] '
            f'"float conedeltaangle" [ {_f(cone - start)} ] "rgb I" {_list(light.intensity)}')
