"""The conversions that turn the paper's downloaded archives into the files the bundled scenes load
(docs/assets.md):

- `split_obj`: one material's faces of an OBJ file moved to a file of their own (Sibenik's clear
  window panes, material `staklo`, become sibenik_staklo.obj), with an `mtllib` line that names the
  material file actually beside it.
- `pbrt_to_obj`: Jan Walter's pbrt-v2 export of the LBL conference room as OBJ + MTL: triangle
  meshes as they are, cylinders, disks and spheres tessellated with 16 segments, each shape's
  `Transform` applied, one `usemtl` per shape, pbrt's named materials as MTL materials.

Both work on the text, line by line or token by token, so that vertex coordinates are not rounded
by a mesh library on the way.
"""
from __future__ import annotations

import gzip
import math
import re
from pathlib import Path

import numpy as np

from ..errors import UserError, counted

SEGMENTS = 16  # around a cylinder, disk or sphere; a sphere has SEGMENTS // 2 rings


# ------------------------------------------------------------------------------------------- OBJ split

def _mtllib(src: Path, names: list[str]) -> str:
    """The `mtllib` line for files written beside `src`: the upstream names where they exist, else
    the one .mtl file beside it (an exporter's leftover name such as untitled.mtl)."""
    if names and all((src.parent / n).is_file() for n in names):
        return "mtllib " + " ".join(names)
    found = sorted(p.name for p in src.parent.glob("*.mtl"))
    if len(found) != 1:
        raise UserError(f"{src}: mtllib {' '.join(names) or '(none)'}: not beside it, and "
                        f"{counted(len(found), 'other .mtl file')} to use instead; put the archive's .mtl file there")
    return f"mtllib {found[0]}"


def _absolute(index: bytes, count: int) -> int:
    i = int(index)
    return i if i > 0 else count + 1 + i  # OBJ's negative indices count back from the last element


def split_obj(src: Path, material: str, rest: Path, part: Path, header: str) -> tuple[int, int]:
    """Write the faces of `src` whose material is `material` to `part`, the others to `rest` (which
    may be `src` itself); each file holds only the vertices (v, vt, vn) its faces use, renumbered,
    their lines copied as they are. `header` (comment text) opens both. Returns the face counts
    (rest, part); a source without such faces is an error (the archive is not the one expected)."""
    elements = {b"v": [], b"vt": [], b"vn": []}
    out = {False: _ObjOut(), True: _ObjOut()}
    state, current, libs = {}, None, []
    with open(src, "rb") as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            tag = parts[0]
            if tag in elements:
                elements[tag].append(b" ".join(parts))
            elif tag == b"mtllib":
                libs += [p.decode() for p in parts[1:]]
            elif tag == b"usemtl":
                current = parts[1].decode() if len(parts) > 1 else None
                state[b"usemtl"] = b" ".join(parts)
            elif tag in (b"g", b"o", b"s"):
                state[tag] = b" ".join(parts)
            elif tag == b"f":
                corners = [c.split(b"/") for c in parts[1:]]
                out[current == material].face(corners, elements, state)
    if not out[True].faces:
        raise UserError(f"{src}: no faces with `usemtl {material}`; this is not the archive docs/assets.md "
                        "describes (it may have changed upstream): report it, or put the converted files in place")
    lib = _mtllib(src, libs)
    for target, o in ((part, out[True]), (rest, out[False])):
        o.write(target, header, lib, elements)
    return len(out[False].faces), len(out[True].faces)


class _ObjOut:
    """One output file of `split_obj`: its elements in first-use order and its face lines."""

    def __init__(self):
        self.used = {b"v": {}, b"vt": {}, b"vn": {}}
        self.faces, self._state = [], {}

    def face(self, corners, elements, state):
        for key, line in state.items():  # group, object, smoothing and material lines that changed
            if self._state.get(key) != line:
                self.faces.append(line)
                self._state[key] = line
        words = []
        for corner in corners:
            ids = []
            for tag, index in zip((b"v", b"vt", b"vn"), corner):
                if index:
                    used = self.used[tag]
                    n = used.setdefault(_absolute(index, len(elements[tag])) - 1, len(used) + 1)
                    ids.append(b"%d" % n)
                else:
                    ids.append(b"")
            words.append(b"/".join(ids))
        self.faces.append(b"f " + b" ".join(words))

    def write(self, path: Path, header: str, lib: str, elements: dict):
        lines = [f"# {h}".encode() for h in header.splitlines()] + [lib.encode()]
        for tag, used in self.used.items():
            lines += [elements[tag][i] for i in used]
        lines += self.faces
        path.write_bytes(b"\n".join(lines) + b"\n")


# ------------------------------------------------------------------------------------------ pbrt-v2 to OBJ

_TOKEN = re.compile(rb'"[^"]*"|\[|\]|[^\s\[\]"]+')
_DIRECTIVE = re.compile(rb"[A-Z][A-Za-z]*")


def _statements(text: bytes):
    """pbrt's statements as (directive, [argument, ...]): a quoted string (unquoted), a bracketed
    list (a list of byte strings) or a bare word."""
    text = re.sub(rb"#[^\n]*", b"", text)
    name, args, values = None, [], None
    for tok in _TOKEN.findall(text):
        if values is not None:
            if tok == b"]":
                args.append(values)
                values = None
            else:
                values.append(tok.strip(b'"'))
        elif tok == b"[":
            values = []
        elif _DIRECTIVE.fullmatch(tok):
            if name is not None:
                yield name, args
            name, args = tok.decode(), []
        else:
            args.append(tok.strip(b'"') if tok.startswith(b'"') else tok)
    if name is not None:
        yield name, args


def _params(args) -> dict[str, list[bytes]]:
    """The "type name" value pairs of a statement, by name."""
    out = {}
    for i in range(len(args) - 1):
        if isinstance(args[i], bytes) and b" " in args[i]:
            value = args[i + 1]
            out[args[i].split()[1].decode()] = value if isinstance(value, list) else [value]
    return out


def _ring(radius: float, z: float) -> np.ndarray:
    phi = 2.0 * math.pi * np.arange(SEGMENTS) / SEGMENTS
    return np.column_stack([radius * np.cos(phi), radius * np.sin(phi), np.full(SEGMENTS, z)])


def _around(a: int, b: int, outer_first: bool = False) -> np.ndarray:
    """Two triangles per segment between the rings starting at vertices a and b (SEGMENTS each):
    (a_j, a_j+1, b_j+1) and (a_j, b_j+1, b_j), or with `outer_first` (a_j, b_j, b_j+1) and
    (a_j, b_j+1, a_j+1)."""
    j = np.arange(SEGMENTS)
    k = (j + 1) % SEGMENTS
    pairs = ([a + j, b + j, b + k], [a + j, b + k, a + k]) if outer_first else \
        ([a + j, a + k, b + k], [a + j, b + k, b + j])
    return np.stack([np.column_stack(t) for t in pairs], axis=1).reshape(-1, 3)


def _shape(kind: str, p: dict, where: str):
    """Object-space vertices (N, 3) and 0-based faces (F, 3) of a pbrt shape."""
    def f(key, default=None):
        if key not in p:
            if default is None:
                raise UserError(f"{where}: Shape \"{kind}\" has no \"{key}\"")
            return default
        return float(p[key][0])

    if kind == "trianglemesh":
        return (np.array(p["P"], dtype=np.float64).reshape(-1, 3),
                np.array(p["indices"], dtype=np.int64).reshape(-1, 3))
    if f("phimax", 360.0) != 360.0:
        raise UserError(f"{where}: Shape \"{kind}\" with \"phimax\" {f('phimax')}: only whole shapes are converted")
    r = f("radius", 1.0)
    if kind == "cylinder":
        return np.vstack([_ring(r, f("zmin", -1.0)), _ring(r, f("zmax", 1.0))]), _around(0, SEGMENTS)
    if kind == "disk":
        h, inner = f("height", 0.0), f("innerradius", 0.0)
        if inner > 0.0:  # an annulus: (inner_j, outer_j, outer_j+1) and (inner_j, outer_j+1, inner_j+1)
            return np.vstack([_ring(inner, h), _ring(r, h)]), _around(0, SEGMENTS, outer_first=True)
        j = np.arange(SEGMENTS)
        return (np.vstack([[0.0, 0.0, h], _ring(r, h)]),
                np.column_stack([np.zeros(SEGMENTS, np.int64), 1 + j, 1 + (j + 1) % SEGMENTS]))
    if kind == "sphere":
        if f("zmin", -r) != -r or f("zmax", r) != r:
            raise UserError(f"{where}: Shape \"sphere\" with \"zmin\"/\"zmax\": only whole spheres are converted")
        rings, cols = SEGMENTS // 2, SEGMENTS + 1  # rows pole to pole; the seam column repeated
        th = math.pi * np.arange(rings + 1) / rings
        ph = 2.0 * math.pi * np.arange(cols) / SEGMENTS
        v = np.stack([np.outer(np.sin(th), np.cos(ph)), np.outer(np.sin(th), np.sin(ph)),
                      np.outer(np.cos(th), np.ones(cols))], axis=-1).reshape(-1, 3) * r
        i, j = np.meshgrid(np.arange(rings), np.arange(SEGMENTS), indexing="ij")
        a, b = (i * cols + j).ravel(), ((i + 1) * cols + j).ravel()
        return v, np.stack([np.column_stack([a, b, b + 1]), np.column_stack([a, b + 1, a + 1])], axis=1).reshape(-1, 3)
    raise UserError(f'{where}: Shape "{kind}" is not converted (trianglemesh, cylinder, disk and sphere are)')


MTL_HEADER = ("# Materials of the LBL conference room, translated from pbrt named materials (Jan Walter export).\n"
              "# pbrt type is kept as a comment; mirror -> Ks=Kr, glass -> Tf=Kt & Ni=index; Ke set for pbrt "
              "area-light materials.\n")


def _material(name: str, p: dict, emission, where: str) -> str:
    kind = p.get("type", [b"?"])[0].decode()

    def colour(key):
        return " ".join(x.decode() for x in p[key])

    lines = [f"newmtl {name}", f"# pbrt type: {kind}"]
    if kind in ("matte", "plastic"):
        lines.append(f"Kd {colour('Kd')}")
        if kind == "plastic":
            lines += [f"Ks {colour('Ks')}", f"# pbrt roughness {p['roughness'][0].decode()}"]
    elif kind == "mirror":
        lines += ["Kd 0 0 0", f"Ks {colour('Kr')}", "illum 3"]
    elif kind == "glass":
        lines += ["Kd 0 0 0", f"Ks {colour('Kr')}", f"Tf {colour('Kt')}", f"Ni {p['index'][0].decode()}", "d 0.2",
                  "illum 7"]
    else:
        raise UserError(f'{where}: MakeNamedMaterial "{name}": type "{kind}" is not converted '
                        "(matte, plastic, mirror and glass are)")
    if emission is not None:
        lines.append("Ke " + " ".join(f"{float(x):g}" for x in emission))
    return "\n".join(lines) + "\n"


def pbrt_to_obj(src: Path, obj: Path, mtl: Path, header: str) -> int:
    """Convert the world block of a (gzipped) pbrt-v2 file, in the subset the LBL conference room's
    export uses (AttributeBegin/End, Transform, MakeNamedMaterial, NamedMaterial, AreaLightSource,
    Shape), to `obj` and `mtl` (named by its `mtllib` line). Returns the number of triangles."""
    data = src.read_bytes()
    text = gzip.decompress(data) if src.suffix == ".gz" else data
    identity = np.eye(4)
    stack, ctm, current = [], identity, None
    materials, emission, order = {}, {}, []
    vertices, faces, count, world = [], [], 0, False
    for n, (name, args) in enumerate(_statements(text)):
        where = f"{src}: statement {n + 1} ({name})"
        if name == "WorldBegin":
            world, ctm = True, identity
        elif not world:
            continue
        elif name == "WorldEnd":
            break
        elif name == "AttributeBegin":
            stack.append((ctm, current))
        elif name == "AttributeEnd":
            ctm, current = stack.pop()
        elif name == "Transform":
            ctm = np.array(args[0], dtype=np.float64).reshape(4, 4)  # row vectors: [p, 1] @ ctm
        elif name == "MakeNamedMaterial":
            key = args[0].decode()
            materials[key] = _params(args[1:])
            order.append(key)
        elif name == "NamedMaterial":
            current = args[0].decode()
        elif name == "AreaLightSource":
            emission[current] = _params(args[1:])["L"]
        elif name == "Shape":
            kind = args[0].decode()
            v, f = _shape(kind, _params(args[1:]), where)
            if kind != "trianglemesh" and np.linalg.det(ctm[:3, :3]) < 0.0:
                f = f[:, [0, 2, 1]]  # a mirroring transform: keep the tessellated surface facing out
            v = v @ ctm[:3, :3] + ctm[3, :3]
            lines = [f"usemtl {current}"] + [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v]
            lines += [f"f {a} {b} {c}" for a, b, c in f + count + 1]
            faces.append(len(f))
            vertices.append("\n".join(lines))
            count += len(v)
        else:
            raise UserError(f"{where}: not converted (the LBL conference room's export does not use it)")
    if not faces:
        raise UserError(f"{src}: no shapes inside WorldBegin ... WorldEnd; is it the archive docs/assets.md names?")
    head = "".join(f"# {h}\n" for h in header.splitlines())
    obj.write_text(f"{head}mtllib {mtl.name}\n" + "\n".join(vertices) + "\n", encoding="utf-8")
    mtl.write_text(MTL_HEADER + "".join("\n" + _material(k, materials[k], emission.get(k), f"{src}") for k in order),
                   encoding="utf-8")
    return sum(faces)
