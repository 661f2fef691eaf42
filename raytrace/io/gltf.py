"""glTF 2.0 scenes in and out (docs/formats/gltf.md): the glTF 2.0 specification, KHR_lights_punctual,
KHR_materials_volume, KHR_materials_ior, KHR_materials_transmission and the KHR_materials_volume_scatter
draft.

JSON and binary buffers are parsed here with numpy rather than through trimesh: trimesh reads the
geometry but neither lights, cameras nor the KHR material extensions, and reading the buffers
ourselves lets every accessor be checked (bounds, memory budget, finiteness) before it is allocated.

Units: glTF lengths are metres and ours are scene units (1:1). Lights: candela / 683 = W/sr (point,
spot), lux / 683 = W/m^2 (directional), the luminous efficacy Blender's exporter uses. A light or a
camera looks down its node's -Z with +Y up. Media: sigma_t = -ln(attenuationColor) / attenuationDistance.

What the importer approximates (a texture by its mean, metals as diffuse, ...) it says in one line
each through Python's `warnings` (category `GltfNote`); what it cannot read is a UserError.
"""
from __future__ import annotations

import base64
import copy
import json
import math
import re
import struct
import warnings
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from ..errors import UserError, counted
from . import emitters
from .report import ImportNote, Problems, default_camera, grouped, warn

LUMENS_PER_WATT = 683.0  # candela = 683 W/sr, lux = 683 W/m^2 (KHR_lights_punctual; Blender's exporter)
MESH_SEGMENTS = 64  # a disk or sphere light exported as a mesh (--approximate)
DEFAULT_HEIGHT = 512  # image rows for a camera without our `extras`; the width keeps its aspectRatio
DEFAULT_FOV = 45.0  # degrees: the vertical fov of the camera made for a file without one
GLB_MAGIC, JSON_CHUNK, BIN_CHUNK = b"glTF", 0x4E4F534A, 0x004E4942
COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN = 4, 5, 6
READ_EXTENSIONS = {"KHR_lights_punctual", "KHR_materials_volume", "KHR_materials_ior", "KHR_materials_transmission",
                   "KHR_materials_volume_scatter", "KHR_materials_emissive_strength", "KHR_texture_transform",
                   "KHR_mesh_quantization"}
COMPRESSION = ("KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_meshopt_compression")


class GltfNote(ImportNote):
    """What a glTF import or export approximates or leaves out, one line each."""


# -- the KHR_materials_volume_scatter draft's multi-scatter albedo (Kulla & Conty 2017) --------------------

def single_scatter_albedo(multi):
    """rho_ss = 1 - (4.09712 + 4.20863 m - sqrt(9.59217 + 41.6808 m + 17.7126 m^2))^2, the draft's
    inversion of the multi-scatter albedo m; m = 0 (the draft's default) is no scattering."""
    m = np.asarray(multi, dtype=np.float64)
    rho = 1.0 - (4.09712 + 4.20863 * m - np.sqrt(9.59217 + 41.6808 * m + 17.7126 * m * m)) ** 2
    return np.where(m > 0.0, np.clip(rho, 0.0, 1.0), 0.0)


def multi_scatter_albedo(rho):
    """The m in [0, 1] whose `single_scatter_albedo` is rho (bisection to double precision: the
    draft's map is increasing); albedos below its value at m = 0 (6.4e-6) give m = 0."""
    lo, hi = np.zeros_like(np.asarray(rho, dtype=np.float64)), np.ones_like(np.asarray(rho, dtype=np.float64))
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        below = 1.0 - (4.09712 + 4.20863 * mid - np.sqrt(9.59217 + 41.6808 * mid + 17.7126 * mid * mid)) ** 2 < rho
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return np.where(np.asarray(rho) > 0.0, hi, 0.0)


# -- rotations ---------------------------------------------------------------------------------------

def quaternion_matrix(q) -> np.ndarray:
    """The rotation of the unit quaternion (x, y, z, w), glTF's order."""
    x, y, z, w = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def matrix_quaternion(m) -> list[float]:
    """The unit quaternion (x, y, z, w) of a rotation matrix (Shepperd's method: the largest pivot)."""
    m = np.asarray(m, dtype=np.float64)
    t = np.trace(m)
    k = int(np.argmax([m[0, 0], m[1, 1], m[2, 2], t]))
    if k == 3:
        q = [m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1], 1.0 + t]
    else:
        i, j, l = k, (k + 1) % 3, (k + 2) % 3
        q = [0.0, 0.0, 0.0, m[l, j] - m[j, l]]
        q[i] = 1.0 + m[i, i] - m[j, j] - m[l, l]
        q[j] = m[j, i] + m[i, j]
        q[l] = m[l, i] + m[i, l]
    q = np.array(q) / np.linalg.norm(q)
    return (q if q[3] >= 0.0 else -q).tolist()


def _look_rotation(forward, up=None) -> np.ndarray:
    """The rotation whose -Z is `forward` and whose +Y is `up` made orthogonal to it (any for None)."""
    f = np.asarray(forward, dtype=np.float64) / np.linalg.norm(forward)
    if up is None:
        up = np.array([0.0, 1.0, 0.0]) if abs(f[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(f, up)
    right /= np.linalg.norm(right)
    return np.column_stack([right, np.cross(right, f), -f])


# -- reading -----------------------------------------------------------------------------------------

def read_scene(path: Path, camera: str | None = None) -> dict:
    """The scene dict of a .gltf / .glb file: meshes as inline triangles in world space, materials as
    reflectances or interiors, KHR_lights_punctual lights, and the first perspective camera (or the
    one whose node or camera is named `camera`)."""
    problems = Problems(str(path))
    try:
        reader = _Reader(Path(path), problems)
        raw = reader.scene(camera)
    except UserError as exc:
        problems.check(fatal=exc)
    except (TypeError, AttributeError, KeyError, IndexError, ValueError, OverflowError) as exc:
        # a value of the wrong type or range that the checks above did not name
        problems.check(fatal=UserError(f"{path}: malformed glTF ({type(exc).__name__}: {exc}); fix the file or "
                                       "export it again"))
    problems.check()
    warn([f"{path}: {line}" for line in grouped(reader.notes)], GltfNote)
    return raw


def _json(text: str, source: str) -> dict:
    """JSON with every number finite (NaN, Infinity and overflowing literals refused with their line)."""
    def refuse(token, what="is not finite; glTF numbers must be finite"):
        where = re.search(r'(?<![\w."])' + re.escape(token) + r'(?![\w."])', text)
        line = text.count("\n", 0, where.start()) + 1 if where else "?"
        raise UserError(f"{source}: the number {token[:20]} at line {line} {what}")

    def number(token):
        value = float(token)
        return value if math.isfinite(value) else refuse(token)

    def integer(token):
        value = int(token)
        return value if abs(value) < 2 ** 63 else refuse(token, "is beyond 64-bit integers; fix the file")

    try:
        doc = json.loads(text, parse_constant=refuse, parse_float=number, parse_int=integer)
    except json.JSONDecodeError as exc:
        raise UserError(f"{source}: malformed JSON at line {exc.lineno} column {exc.colno} ({exc.msg}); "
                        "fix the file or export it again") from None
    except RecursionError:
        raise UserError(f"{source}: malformed JSON (nested too deeply); fix the file or export it again") from None
    if not isinstance(doc, dict):
        raise UserError(f"{source}: the JSON is not a glTF object; export the scene as glTF 2.0")
    return doc


class _Reader:
    def __init__(self, path: Path, problems: Problems):
        self.path, self.source, self.problems = path, str(path), problems
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise UserError(f"{path}: cannot read the file ({exc.strerror}); check the path and its permissions") from None
        self.bin = None
        if data[:4] == GLB_MAGIC:
            text = self._glb(data)
        else:
            try:
                text = data.decode("utf-8-sig")
            except UnicodeDecodeError:
                self.fail("", "neither a .glb (binary) nor UTF-8 JSON", "export the scene as glTF 2.0")
        self.doc = _json(text, self.source)
        version = str(self._get(self.doc, "asset", dict, {}).get("version", ""))
        if not version.startswith("2."):
            self.fail("asset.version", f"{version or 'missing'}: only glTF 2.0 is read", "export the scene as glTF 2.0")
        self.buffers: dict[int, bytes] = {}
        from ..options import MEMORY_SHARE, physical_memory

        self.budget = MEMORY_SHARE * physical_memory()  # bytes the decoded accessors may take in all
        self.notes: list[tuple[str, str]] = []  # (key, text), said grouped by kind once the file is read

    # messages
    def fail(self, key: str, problem: str, fix: str):
        raise UserError(f"{self.source}: {key + ': ' if key else ''}{problem}; {fix}")

    def note(self, key: str, text: str):
        self.notes.append((key, text))

    def _glb(self, data: bytes) -> str:
        if len(data) < 20:
            self.fail("", "a .glb shorter than its header", "export the scene again")
        _, version, length = struct.unpack_from("<4sII", data)
        if version != 2:
            self.fail("", f"GLB container version {version}", "export the scene as glTF 2.0")
        if length != len(data):
            self.fail("", f"the GLB header says {counted(length, 'byte')} but the file has {len(data)} (truncated?)",
                      "copy or export the file again")
        chunks, at = [], 12
        while at + 8 <= length:
            size, kind = struct.unpack_from("<II", data, at)
            if at + 8 + size > length:
                self.fail("", f"a GLB chunk at byte {at} runs past the end of the file", "copy or export the file again")
            chunks.append((kind, data[at + 8:at + 8 + size]))
            at += 8 + size
        if not chunks or chunks[0][0] != JSON_CHUNK:
            self.fail("", "the GLB has no JSON chunk first", "export the scene again")
        self.bin = next((c for k, c in chunks[1:] if k == BIN_CHUNK), None)
        try:
            return chunks[0][1].decode("utf-8")
        except UnicodeDecodeError:
            self.fail("", "the GLB's JSON chunk is not UTF-8", "export the scene again")

    # typed access to the JSON, with the key in every message
    def _get(self, obj, key, kind, default=None, where=""):
        value = obj.get(key)
        if value is None:  # absent or null
            return default
        if not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
            self.fail(f"{where}{key}", f"expected {getattr(kind, '__name__', 'a number')}, got {value!r}",
                      "fix the file or export it again")
        return value

    def item(self, table: str, index) -> dict:
        items = self._get(self.doc, table, list, [])
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(items) \
                or not isinstance(items[index], dict):
            self.fail(f"{table}[{index}]", f"no such entry (the file has {len(items)})", "fix the reference")
        return items[index]

    def number(self, obj, key, where, default=None, lo=-math.inf, hi=math.inf):
        value = obj.get(key, default)
        if value is None:
            self.fail(f"{where}.{key}", "missing", "fix the file or export it again")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
            self.fail(f"{where}.{key}", f"{value!r} is not a number in [{lo:g}, {hi:g}]", "fix the file or export it again")
        return float(value)

    def vector(self, obj, key, where, n, default=None, lo=-math.inf, hi=math.inf) -> np.ndarray:
        value = obj.get(key, default)
        if not isinstance(value, list) or len(value) != n or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and lo <= v <= hi for v in value):
            self.fail(f"{where}.{key}", f"expected {n} numbers in [{lo:g}, {hi:g}], got {value!r}",
                      "fix the file or export it again")
        return np.array(value, dtype=np.float64)

    # buffers and accessors
    def buffer(self, i) -> bytes:
        b, key = self.item("buffers", i), f"buffers[{i}]"
        if i in self.buffers:
            return self.buffers[i]
        size = int(self.number(b, "byteLength", key, lo=1))
        uri = self._get(b, "uri", str, where=f"{key}.")
        if uri is None:
            if i != 0 or self.bin is None:
                self.fail(key, "has no uri and the file no binary chunk", "export the scene as .glb or with its .bin")
            data = self.bin
        elif uri.startswith("data:"):
            try:
                data = base64.b64decode(uri.split(",", 1)[1], validate=True)
            except (IndexError, ValueError):
                self.fail(f"{key}.uri", "a data URI that is not base64", "export the scene again")
        else:
            file = self.path.parent / unquote(uri)
            try:
                data = file.read_bytes()
            except OSError:
                self.fail(f"{key}.uri", f"{uri!r} is missing beside the file ({file})",
                          f"copy {Path(uri).name} next to {self.path.name} or export the scene as .glb")
        if len(data) < size:
            self.fail(f"{key}.byteLength", f"says {counted(size, 'byte')} but the data has {len(data)}",
                      "copy the buffer again or export the scene again")
        self.buffers[i] = data
        return data

    def accessor(self, i, integer=False) -> np.ndarray:
        """Accessor i as a (count, width) float64 array (int64 for indices), checked before allocation."""
        a, key = self.item("accessors", i), f"accessors[{i}]"
        ctype = a.get("componentType")
        if not isinstance(ctype, int) or ctype not in COMPONENTS or not isinstance(a.get("type"), str) \
                or a["type"] not in WIDTHS:
            self.fail(key, f"componentType {ctype!r} / type {a.get('type')!r} is not a glTF accessor format",
                      "fix the file or export it again")
        dtype, width = np.dtype(COMPONENTS[ctype]).newbyteorder("<"), WIDTHS[a["type"]]
        if integer and (dtype.kind == "f" or width != 1):
            self.fail(key, "indices must be unsigned integer SCALARs", "fix the file or export it again")
        count = int(self.number(a, "count", key, lo=1))
        need = count * width * 8
        if need > self.budget:
            self.fail(f"{key}.count", f"{count} elements would take {need / 2**30:.3g} GiB, more than the memory "
                      f"budget of {self.budget / 2**30:.3g} GiB", "check the file or simplify the mesh")
        self.budget -= need
        if "sparse" in a:
            self.fail(f"{key}.sparse", "sparse accessors are not read", "export the scene without sparse data")
        if "bufferView" not in a:
            return np.zeros((count, width), dtype=np.int64 if integer else np.float64)
        view, vkey = self.item("bufferViews", a["bufferView"]), f"bufferViews[{a['bufferView']}]"
        if any(e in self._get(view, "extensions", dict, {}) for e in COMPRESSION):
            self.fail(vkey, "meshopt-compressed data is not decoded", "export the scene without compression")
        data = self.buffer(view.get("buffer"))
        start, length = int(self.number(view, "byteOffset", vkey, 0, lo=0)), int(self.number(view, "byteLength", vkey, lo=1))
        offset = int(self.number(a, "byteOffset", key, 0, lo=0))
        size = dtype.itemsize * width
        stride = int(self.number(view, "byteStride", vkey, size, lo=size, hi=252))
        if start + length > len(data) or offset + stride * (count - 1) + size > length:
            self.fail(key, f"{counted(count, 'element runs', 'elements run')} past the end of {vkey} or its buffer",
                      "fix the file or export it again")
        arr = np.ndarray((count, width), dtype=dtype, buffer=data, offset=start + offset, strides=(stride, dtype.itemsize))
        if integer:
            return arr.astype(np.int64)
        out = arr.astype(np.float64)
        if dtype.kind != "f" and a.get("normalized"):
            out = np.maximum(out / np.iinfo(dtype).max, -1.0)
        if not np.all(np.isfinite(out)):
            bad = int(np.sum(~np.all(np.isfinite(out), axis=1)))
            self.fail(key, f"{bad} of its {counted(count, 'element')} {'is' if bad == 1 else 'are'} not finite "
                      "(nan or inf)", "fix the mesh and export it again")
        return out

    # the node graph
    def scene(self, camera_name: str | None) -> dict:
        for ext in self._get(self.doc, "extensionsRequired", list, []):
            if not isinstance(ext, str) or ext not in READ_EXTENSIONS:
                what = "compressed meshes are not decoded" if ext in COMPRESSION else "this extension is not read"
                with self.problems.each():  # the file's other problems are listed too
                    self.fail("extensionsRequired", f"{ext}: {what}", "export the scene without it")
        nodes = self._get(self.doc, "nodes", list, [])
        scenes = self._get(self.doc, "scenes", list, [])
        if scenes:
            s = self.doc.get("scene", 0)
            roots = self._get(self.item("scenes", s), "nodes", list, [], f"scenes[{s}].")
        else:
            children = {c for n in nodes if isinstance(n, dict) for c in n.get("children", [])}
            roots = [i for i in range(len(nodes)) if i not in children]
        self.shapes, self.lights, self.cameras = [], [], []
        stack = [(r, np.eye(4), ()) for r in reversed(roots)]
        while stack:
            i, parent, path = stack.pop()
            if i in path:
                self.fail(f"nodes[{i}].children", "the node is its own ancestor (a cycle)", "fix the node hierarchy")
            node = self.item("nodes", i)
            world = parent @ self.local(node, f"nodes[{i}]")
            if not np.all(np.isfinite(world)):
                self.fail(f"nodes[{i}]", "its transform overflows", "use smaller scales or translations")
            self.visit(i, node, world)
            stack += [(c, world, path + (i,)) for c in reversed(self._get(node, "children", list, [], f"nodes[{i}]."))]
        raw = {"shape": self.shapes, "light": self.lights}
        cam = self.camera(camera_name)
        if cam is None:
            cam = default_camera(raw, DEFAULT_FOV, DEFAULT_HEIGHT)
            self.note("cameras", f"the file has no perspective camera: a default one looks at the centre "
                      f"{_short(cam['look_at'])} of the shapes' bounding sphere from +z of it, the sphere in view "
                      f"(fov {DEFAULT_FOV:g}, {DEFAULT_HEIGHT} x {DEFAULT_HEIGHT}); change it with --set "
                      "camera.position=[x, y, z] --set camera.look_at=[x, y, z]")
        raw["camera"] = cam
        extras = self.item("scenes", self.doc.get("scene", 0)).get("extras", {}) if scenes else {}
        for table in ("medium", "background", "render"):  # our own tables, written by `export`
            if isinstance(extras, dict) and isinstance(extras.get(table), dict):
                raw[table] = copy.deepcopy(extras[table])
        return raw

    def local(self, node, key) -> np.ndarray:
        if "matrix" in node:
            return self.vector(node, "matrix", key, 16).reshape(4, 4).T  # column-major
        m = np.eye(4)
        rotation = self.vector(node, "rotation", key, 4, [0.0, 0.0, 0.0, 1.0])
        if not np.linalg.norm(rotation) > 0.0:
            self.fail(f"{key}.rotation", "a zero quaternion", "use a unit quaternion (x, y, z, w)")
        m[:3, :3] = quaternion_matrix(rotation) * self.vector(node, "scale", key, 3, [1.0, 1.0, 1.0])[None, :]
        m[:3, 3] = self.vector(node, "translation", key, 3, [0.0, 0.0, 0.0])
        return m

    def visit(self, i, node, world):
        key = f"nodes[{i}]"
        if "mesh" in node:
            mesh_key = f"meshes[{node['mesh']}]"
            for j, prim in enumerate(self._get(self.item("meshes", node["mesh"]), "primitives", list, [], f"{mesh_key}.")):
                with self.problems.each():  # a primitive that cannot be read is listed and left out
                    self.primitive(prim, f"{mesh_key}.primitives[{j}]", world)
        if "camera" in node:
            self.cameras.append((node.get("name"), node["camera"], world, key))
        light = self._get(node, "extensions", dict, {}).get("KHR_lights_punctual")
        if isinstance(light, dict) and "light" in light:
            with self.problems.each():
                self.lights.append(self.light(light["light"], world, key))

    def primitive(self, prim, key, world):
        if not isinstance(prim, dict):
            self.fail(key, "expected an object", "fix the file or export it again")
        if any(e in self._get(prim, "extensions", dict, {}) for e in COMPRESSION):
            self.fail(key, "Draco-compressed meshes are not decoded", "export the scene without mesh compression")
        mode = prim.get("mode", TRIANGLES)
        if mode not in (TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN):
            self.note(key, f"mode {mode} (points or lines) has no surface; left out")
            return
        attributes = self._get(prim, "attributes", dict, {}, f"{key}.")
        if "POSITION" not in attributes:
            self.fail(f"{key}.attributes.POSITION", "missing", "export the mesh with its vertex positions")
        pos = self.accessor(attributes["POSITION"])
        if pos.shape[1] != 3:
            self.fail(f"{key}.attributes.POSITION", "is not VEC3", "fix the file or export it again")
        idx = self.accessor(prim["indices"], integer=True).ravel() if "indices" in prim else np.arange(len(pos))
        if len(idx) and (idx.min() < 0 or idx.max() >= len(pos)):
            self.fail(f"{key}.indices", f"indices beyond its {counted(len(pos), 'vertex', 'vertices')}",
                      "fix the mesh and export it again")
        if mode == TRIANGLES:
            faces = idx[:len(idx) // 3 * 3].reshape(-1, 3)
        else:
            n = np.arange(max(len(idx) - 2, 0))
            if mode == TRIANGLE_STRIP:  # every other triangle reversed to keep the winding
                faces = np.stack([idx[n + n % 2], idx[n + 1 - n % 2], idx[n + 2]], axis=1)
            else:
                faces = np.stack([np.full_like(n, idx[0]), idx[n + 1], idx[n + 2]], axis=1)
        if not len(faces):
            self.note(key, "holds no triangle; left out")
            return
        with np.errstate(over="ignore", invalid="ignore"):
            vertices = pos @ world[:3, :3].T + world[:3, 3]
        if not np.all(np.isfinite(vertices)):
            self.fail(key, "its node transform makes vertices overflow", "use smaller scales or translations")
        if np.linalg.det(world[:3, :3]) < 0.0:  # the spec: a mirroring node turns the front face's winding
            faces = faces[:, ::-1]
        shape = {"primitive": "triangles", "vertices": vertices, "faces": faces}
        if "NORMAL" in attributes:  # else flat, as the spec asks (meshes.py: `triangles` without normals)
            shape["normals"] = self.normals(attributes["NORMAL"], len(pos), world, f"{key}.attributes.NORMAL")
        shape.update(self.material(prim.get("material"), key))
        self.shapes.append(shape)

    def normals(self, index, count, world, key) -> np.ndarray:
        """A NORMAL accessor's unit vectors, by the node's inverse transpose."""
        n = self.accessor(index)
        if n.shape != (count, 3):
            self.fail(key, f"expected {count} VEC3 normals, got {n.shape[0]} of width {n.shape[1]}",
                      "export the mesh again with its normals")
        n = n @ np.linalg.inv(world[:3, :3])
        length = np.linalg.norm(n, axis=1, keepdims=True)
        if not np.all(length > 0.0):
            self.fail(key, "a zero normal", "export the mesh again with its normals (or without them: flat)")
        return n / length

    # materials
    def material(self, index, prim_key) -> dict:
        """{"reflectance": ...} or {"interior": ...} for material `index` (None: glTF's default material)."""
        if index is None:
            self.note(prim_key, "has no material: glTF's default, white (reflectance 1)")
            return {"reflectance": [1.0, 1.0, 1.0]}
        m, key = self.item("materials", index), f"materials[{index}]"
        pbr = self._get(m, "pbrMetallicRoughness", dict, {}, f"{key}.")
        ext = self._get(m, "extensions", dict, {}, f"{key}.")
        if self.number(pbr, "metallicFactor", f"{key}.pbrMetallicRoughness", 1.0, 0.0, 1.0) > 0.0:
            self.note(f"{key}.pbrMetallicRoughness.metallicFactor", "metals are rendered as diffuse surfaces of their "
                      "base colour (the default metallicFactor is 1)")
        emission = self.emission(m, ext, key)
        if not m.get("doubleSided", False):
            self.note(f"{key}.doubleSided", "single-sided in glTF; rendered two-sided (both faces reflect)"
                      + (", emitting from its front face" if emission else ""))
        volume = self.volume(ext, key)
        if volume is not None:
            if emission:
                self.note(f"{key}.emissiveFactor", "emission on a volume material (KHR_materials_volume) is not "
                          "rendered")
            return {"interior": volume}
        if self._get(ext, "KHR_materials_transmission", dict, {}).get("transmissionFactor", 0.0):
            self.note(f"{key}.extensions.KHR_materials_transmission", "transmission without a volume "
                      "(KHR_materials_volume thicknessFactor > 0) is not rendered; the surface is opaque")
        rgb = self.vector(pbr, "baseColorFactor", f"{key}.pbrMetallicRoughness", 4, [1.0] * 4, 0.0, 1.0)[:3]
        texture = pbr.get("baseColorTexture")
        if isinstance(texture, dict) and "index" in texture:
            mean = self.texture_mean(texture["index"])
            self.note(f"{key}.pbrMetallicRoughness.baseColorTexture", "replaced by its mean colour "
                      f"{np.round(mean, 4).tolist()} (linear) times baseColorFactor")
            rgb = rgb * mean
        return {"reflectance": rgb.tolist(), **emission}

    def emission(self, m, ext, key) -> dict:
        """{"emission": radiance, "two_sided": doubleSided} of an emissive material, else {}: the radiance is
        emissiveFactor (times the emissive texture's mean) x KHR_materials_emissive_strength's emissiveStrength.

        Blender's exporter writes a material's Emission x Emission Strength S unscaled
        (gltf2_blender_gather_materials_emission.py) and a lamp of P watts as P / 4 pi x 683 candela
        (gltf2_blender_gather_lights.py: read here as P / 4 pi W/sr). In Cycles a square of strength S and
        area A lights the point below it pi times as much as a lamp of 4 S A watts
        (tests/data/gltf/make_emitter.py), as a radiance S does beside P / 4 pi W/sr: S is our radiance
        (docs/formats/gltf.md)."""
        rgb = self.vector(m, "emissiveFactor", key, 3, [0.0, 0.0, 0.0], 0.0)
        strength = self.number(self._get(ext, "KHR_materials_emissive_strength", dict, {}, f"{key}.extensions."),
                               "emissiveStrength", f"{key}.extensions.KHR_materials_emissive_strength", 1.0, 0.0)
        texture = m.get("emissiveTexture")
        if isinstance(texture, dict) and "index" in texture and np.any(rgb):
            mean = self.texture_mean(texture["index"])
            self.note(f"{key}.emissiveTexture", f"replaced by its mean colour {np.round(mean, 4).tolist()} (linear) "
                      "times emissiveFactor")
            rgb = rgb * mean
        if not np.any(rgb * strength):
            return {}
        return {"emission": (rgb * strength).tolist(), "two_sided": bool(m.get("doubleSided", False))}

    def texture_mean(self, index) -> np.ndarray:
        """The mean linear RGB of a base-colour texture (sRGB-decoded, IEC 61966-2-1)."""
        import io

        from PIL import Image

        source = self.item("textures", index).get("source")
        image, key = self.item("images", source), f"images[{source}]"
        if "bufferView" in image:
            view = self.item("bufferViews", image["bufferView"])
            start = int(self.number(view, "byteOffset", f"bufferViews[{image['bufferView']}]", 0, lo=0))
            data = self.buffer(view.get("buffer"))[start:start + int(view.get("byteLength", 0))]
        else:
            uri = self._get(image, "uri", str, "", f"{key}.")
            if uri.startswith("data:"):
                data = base64.b64decode(uri.split(",", 1)[-1])
            else:
                try:
                    data = (self.path.parent / unquote(uri)).read_bytes()
                except OSError:
                    self.fail(f"{key}.uri", f"{uri!r} is missing beside the file", f"copy it next to {self.path.name}")
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", Image.DecompressionBombWarning)
                pixels = np.asarray(Image.open(io.BytesIO(data)).convert("RGB"), dtype=np.float64) / 255.0
        except Exception as exc:  # Pillow raises many types for undecodable images
            self.fail(key, f"cannot decode the image ({type(exc).__name__}: {exc})", "use a PNG or JPEG texture")
        linear = np.where(pixels <= 0.04045, pixels / 12.92, ((pixels + 0.055) / 1.055) ** 2.4)
        return linear.reshape(-1, 3).mean(axis=0)

    def volume(self, ext, key) -> dict | None:
        """The interior of a KHR_materials_volume material with thicknessFactor > 0 (else None):
        sigma_t = -ln(attenuationColor) / attenuationDistance, split by the scatter draft's albedo."""
        vol = self._get(ext, "KHR_materials_volume", dict, None, f"{key}.extensions.")
        if vol is None:
            return None
        vkey = f"{key}.extensions.KHR_materials_volume"
        if not self.number(vol, "thicknessFactor", vkey, 0.0, lo=0.0) > 0.0:
            self.note(f"{vkey}.thicknessFactor", "0: a thin wall, no closed volume; the volume is left out")
            return None
        colour = self.vector(vol, "attenuationColor", vkey, 3, [1.0, 1.0, 1.0], 0.0, 1.0)
        if np.any(colour == 0.0):
            self.fail(f"{vkey}.attenuationColor", f"{colour.tolist()} has a 0 channel (infinite absorption)",
                      "use a small positive value")
        distance = self.number(vol, "attenuationDistance", vkey, math.inf, lo=0.0)
        if not distance > 0.0:
            self.fail(f"{vkey}.attenuationDistance", "must be positive", "use the distance light travels to reach "
                      "attenuationColor")
        sigma_t = -np.log(colour) / distance
        scatter = self._get(ext, "KHR_materials_volume_scatter", dict, {}, f"{key}.extensions.")
        skey = f"{key}.extensions.KHR_materials_volume_scatter"
        rho = single_scatter_albedo(self.vector(scatter, "multiscatterColor", skey, 3, [0.0] * 3, 0.0, 1.0))
        g = self.number(scatter, "scatterAnisotropy", skey, 0.0, -1.0, 1.0)
        if abs(g) == 1.0:
            self.fail(f"{skey}.scatterAnisotropy", f"{g:g}: |g| must be below 1", "use a value in (-1, 1)")
        ior = self.number(self._get(ext, "KHR_materials_ior", dict, {}), "ior", f"{key}.extensions.KHR_materials_ior",
                          1.5, lo=1.0)
        interior = {"sigma_a": (sigma_t * (1.0 - rho)).tolist(), "sigma_s": (sigma_t * rho).tolist(), "ior": ior}
        if g != 0.0:
            interior["phase"] = {"type": "hg", "g": g}
        return interior

    def light(self, index, world, node_key) -> dict:
        ext = self._get(self._get(self.doc, "extensions", dict, {}), "KHR_lights_punctual", dict, {}, "extensions.")
        lights = self._get(ext, "lights", list, [], "extensions.KHR_lights_punctual.")
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(lights) \
                or not isinstance(lights[index], dict):
            self.fail(f"{node_key}.extensions.KHR_lights_punctual.light", f"{index!r}: no such light "
                      f"(the file has {len(lights)})", "fix the reference")
        light, key = lights[index], f"extensions.KHR_lights_punctual.lights[{index}]"
        kind = light.get("type")
        if kind not in ("point", "spot", "directional"):
            self.fail(f"{key}.type", f"{kind!r} is not point, spot or directional", "fix the file or export it again")
        power = (self.vector(light, "color", key, 3, [1.0, 1.0, 1.0], 0.0)
                 * self.number(light, "intensity", key, 1.0, lo=0.0) / LUMENS_PER_WATT)
        if "range" in light:
            self.note(f"{key}.range", "not applied (the scene format has no light range yet; glTF's smooth window "
                      "to zero at the range is not applied either): the light reaches beyond it")
        axis = world[:3, :3] @ np.array([0.0, 0.0, -1.0])
        if not np.linalg.norm(axis) > 0.0:
            self.fail(node_key, f"its transform has no -Z direction for light {index}", "remove the zero scale")
        axis = (axis / np.linalg.norm(axis)).tolist()
        if kind == "directional":
            return {"type": "directional", "direction": axis, "irradiance": power.tolist()}
        out = {"type": kind, "position": world[:3, 3].tolist(), "intensity": power.tolist()}
        if kind == "spot":
            spot = self._get(light, "spot", dict, {}, f"{key}.")
            outer = self.number(spot, "outerConeAngle", f"{key}.spot", math.pi / 4, 0.0, math.pi / 2)
            inner = self.number(spot, "innerConeAngle", f"{key}.spot", 0.0, 0.0, outer)
            if not outer > 0.0:
                self.fail(f"{key}.spot.outerConeAngle", "must be positive", "use an angle in (0, pi/2] radians")
            out.update(direction=axis, cone_angle=math.degrees(outer), falloff_start=math.degrees(inner), falloff="gltf")
        return out

    def camera(self, name: str | None) -> dict | None:
        chosen = [c for c in self.cameras if name is None or name in (c[0], self.item("cameras", c[1]).get("name"))]
        if name is not None and not chosen:
            names = sorted({str(n) for c in self.cameras for n in (c[0], self.item("cameras", c[1]).get("name")) if n})
            self.fail("cameras", f"no camera named {name!r}", f"choose one of: {', '.join(names) or '(none)'}")
        for node_name, index, world, node_key in chosen:
            cam, key = self.item("cameras", index), f"cameras[{index}]"
            if cam.get("type") != "perspective":
                self.note(key, f"{cam.get('type')!r} camera left out (only perspective cameras are read)")
                continue
            p = self._get(cam, "perspective", dict, {}, f"{key}.")
            yfov = self.number(p, "yfov", f"{key}.perspective", lo=0.0, hi=math.pi)
            if not 0.0 < yfov < math.pi:
                self.fail(f"{key}.perspective.yfov", f"{yfov!r} radians", "use a vertical field of view in (0, pi)")
            forward, up = world[:3, :3] @ [0.0, 0.0, -1.0], world[:3, :3] @ [0.0, 1.0, 0.0]
            if not np.linalg.norm(np.cross(forward, up)) > 0.0:
                self.fail(node_key, "its transform flattens the camera's view", "remove the zero scale")
            extras = cam.get("extras") if isinstance(cam.get("extras"), dict) else {}
            aspect = self.number(p, "aspectRatio", f"{key}.perspective", 1.0, lo=1e-6, hi=1e6)
            out = {"position": world[:3, 3].tolist(), "look_at": (world[:3, 3] + forward / np.linalg.norm(forward)).tolist(),
                   "up": (up / np.linalg.norm(up)).tolist(), "fov": math.degrees(yfov),
                   "width": max(1, round(DEFAULT_HEIGHT * aspect)), "height": DEFAULT_HEIGHT}
            out.update({k: extras[k] for k in ("width", "height", "spp") if k in extras})  # ours, from `export`
            return out
        return None


def _short(v) -> str:
    return "[" + ", ".join(f"{x:.4g}" for x in v) + "]"


# -- writing -----------------------------------------------------------------------------------------

def export(raw: dict, out: Path, source: str, approximate: bool) -> list[Path]:
    """Write the scene dict `raw` as glTF 2.0: `out` .glb (one file) or .gltf with a .bin beside it.
    Everything is checked before anything is written; returns the files written."""
    return _Writer(raw, Path(out), source, approximate).write()


class _Writer:
    def __init__(self, raw: dict, out: Path, source: str, approximate: bool):
        self.out, self.source, self.approximate = out, source, approximate
        self.raw, self.area, self.emission = emitters.split(raw)  # the emitters: `area_lights`, `material`
        if out.suffix.lower() not in (".glb", ".gltf"):
            self.fail("--out", f"{out.name} is neither .glb nor .gltf", "name the file scene.glb or scene.gltf")
        self.doc = {"asset": {"version": "2.0", "generator": "raytrace-media"}, "scene": 0, "nodes": [],
                    "meshes": [], "materials": [], "accessors": [], "bufferViews": []}
        self.blob = bytearray()
        self.used = set()

    def fail(self, key, problem, fix):
        raise UserError(f"{self.source}: {key}: {problem}; {fix}")

    def approximated(self, key, problem, fix, instead):
        """Refuse what glTF cannot express, or with `approximate` write `instead` and say so."""
        if not self.approximate:
            self.fail(key, f"{problem} (glTF cannot express it)", f"{fix}, or pass --approximate to write {instead}")
        warnings.warn(f"{self.source}: {key}: {problem}; written as {instead} (--approximate)", GltfNote, stacklevel=4)

    def scene(self):
        """The validated scene (scene/format.py)."""
        from ..scene.format import scene_from_dict

        path = Path(self.source)
        return scene_from_dict(self.raw, self.source, path if path.is_file() else None)

    def write(self) -> list[Path]:
        scene = self.scene()
        if not scene.medium.homogeneous:
            self.fail("medium.type", f"{scene.medium.type_name!r}: glTF cannot express height fog or an atmosphere",
                      "export a scene with a homogeneous medium, or --format mitsuba or pbrt")
        if scene.camera.type != "perspective":
            self.fail("camera.type", f"{scene.camera.type!r}: glTF cameras are perspective or orthographic",
                      'use type = "perspective"')
        self.meshes(scene)
        self.area_lights()
        for i, light in enumerate(scene.lights):
            self.light(i, light)
        self.camera(scene)
        extras = {k: copy.deepcopy(self.raw[k]) for k in ("medium", "background", "render") if k in self.raw}
        self.doc["scenes"] = [{"name": scene.name, "nodes": list(range(len(self.doc["nodes"])))}]
        if extras:  # the fog and the rest glTF has no place for: read back by read_scene, ignored by other tools
            self.doc["scenes"][0]["extras"] = extras
        if self.used:
            self.doc["extensionsUsed"] = sorted(self.used)
        return self.save()

    def meshes(self, scene):
        from ..scene.meshes import scene_triangles

        tris, refl, ids, corners = scene_triangles(scene, shape_ids=True, normals=True)
        for i, shape in enumerate(scene.shapes):
            mine = ids == i
            if not np.any(mine):
                continue
            smooth = shape.smooth and corners is not None and (shape.kind in ("mesh", "sphere", "cylinder")
                                                               or "normals" in shape.params)
            groups = [(None, mine)] if shape.interior is not None else [
                (c, mine & np.all(refl == c, axis=1)) for c in np.unique(refl[mine], axis=0)]
            emission = self.emission.get(i)
            if emission is not None and shape.interior is not None:
                self.fail(f"shape[{i}].emission", "an emitting shape that holds a medium cannot be exported",
                          "put the medium in a shape of its own")
            prims = [self.primitive(f"shape[{i}]", tris[sel], corners[sel] if smooth else None,
                                    self.material(i, shape, colour, tris[sel], emission)) for colour, sel in groups]
            self.mesh(f"shape[{i}]", prims)

    def mesh(self, name, prims):
        self.doc["meshes"].append({"name": name, "primitives": prims})
        self.doc["nodes"].append({"name": name, "mesh": len(self.doc["meshes"]) - 1})

    def primitive(self, key, tris, normals, material) -> dict:
        """A triangle list (corners merged by position, and normal when given: NORMAL) of `material`."""
        rows = tris if normals is None else np.concatenate([tris, normals], axis=2)
        table, faces = np.unique(rows.astype(np.float32).reshape(-1, rows.shape[2]), axis=0, return_inverse=True)
        attributes = {"POSITION": self.accessor(np.ascontiguousarray(table[:, :3]), "VEC3", minmax=True)}
        if normals is not None:
            attributes["NORMAL"] = self.accessor(np.ascontiguousarray(table[:, 3:]), "VEC3")
        return {"attributes": attributes, "indices": self.accessor(faces.reshape(-1).astype(np.uint32), "SCALAR"),
                "material": material}

    def area_lights(self):
        """Quad lights as two emitting triangles; disks and spheres as emitting meshes (--approximate); the
        environment: glTF has none (--approximate: left out)."""
        from ..scene.meshes import sphere_triangles

        for i, light in self.area:
            key, kind, src = f"light[{i}]", light.get("type"), self.source
            if kind == "environment":
                self.approximated(key, "an environment light", "remove it", "nothing (the light is left out)")
                continue
            if kind == "quad":
                c = emitters.vector(light.get("corners"), f"{key}.corners", src, rows=4)
                emitters.quad_frame(c, f"{key}.corners", src)
                tris = c[[[0, 1, 2], [0, 2, 3]]]
            else:
                self.approximated(key, f"a {kind} light", "use a quad light", f"an emitting mesh of {MESH_SEGMENTS} "
                                  "segments")
                centre = emitters.vector(light.get("center"), f"{key}.center", src)
                r = emitters.positive(light.get("radius"), f"{key}.radius", src)
                if kind == "sphere":
                    tris = sphere_triangles(centre, r, MESH_SEGMENTS)
                else:  # a fan about the centre, wound towards the normal (+z of its frame)
                    m, r = emitters.disk_frame(light, key, src)
                    a = np.linspace(0.0, 2.0 * math.pi, MESH_SEGMENTS + 1)
                    ring = centre + r * (np.cos(a)[:, None] * m[:3, 0] + np.sin(a)[:, None] * m[:3, 1])
                    tris = np.stack([np.broadcast_to(centre, (MESH_SEGMENTS, 3)), ring[:-1], ring[1:]], axis=1)
            emission = {"emission": light.get("radiance"), "two_sided": light.get("two_sided", False)}
            self.mesh(key, [self.primitive(key, tris, None, self.material(key, None, np.zeros(3), tris, emission))])

    def material(self, i, shape, colour, tris, emission=None) -> int:
        """A material: `colour` (diffuse) or `shape`'s interior; emitting where `emission` ({"emission",
        "two_sided"}: emissiveFactor x emissiveStrength = the radiance (`_Reader.emission`), doubleSided =
        two_sided: the emitting side is the front face)."""
        name = i if isinstance(i, str) else f"shape[{i}]"
        m = {"name": name, "doubleSided": True}
        interior = None if shape is None else shape.interior
        if emission is not None:
            radiance, m["doubleSided"] = emitters.emission_of(emission, name, self.source)
            peak = float(radiance.max())
            m["emissiveFactor"] = (radiance / peak if peak > 1.0 else radiance).tolist()
            if peak > 1.0:  # as Blender's exporter: the factor normalised, its peak as the strength
                m["extensions"] = {"KHR_materials_emissive_strength": {"emissiveStrength": peak}}
                self.used.add("KHR_materials_emissive_strength")
        if interior is None:
            m["pbrMetallicRoughness"] = {"baseColorFactor": [*map(float, colour), 1.0], "metallicFactor": 0.0,
                                         "roughnessFactor": 1.0}
        else:
            key = f"shape[{i}].interior"
            sigma_t = interior.sigma_a + interior.sigma_s
            volume = {"thicknessFactor": float(np.min(np.ptp(tris.reshape(-1, 3), axis=0)) or 1.0)}
            if np.any(sigma_t > 0.0):
                distance = 1.0 / float(np.max(sigma_t))
                volume.update(attenuationColor=np.exp(-sigma_t * distance).tolist(), attenuationDistance=distance)
            ext = {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_volume": volume,
                   "KHR_materials_ior": {"ior": interior.ior}}
            if np.any(interior.sigma_s > 0.0):
                ext["KHR_materials_volume_scatter"] = {
                    "multiscatterColor": multi_scatter_albedo(np.divide(interior.sigma_s, sigma_t, out=np.zeros(3),
                                                                        where=sigma_t > 0.0)).tolist(),
                    "scatterAnisotropy": self.anisotropy(interior, key)}
            m["extensions"] = ext
            self.used |= set(ext)
        self.doc["materials"].append(m)
        return len(self.doc["materials"]) - 1

    def anisotropy(self, interior, key) -> float:
        from ..media.phase import HG, RAYLEIGH

        if interior.phase == RAYLEIGH:
            self.approximated(f"{key}.phase", "Rayleigh scattering", 'use phase = "isotropic" or "hg"',
                              "isotropic scattering (scatterAnisotropy 0, the same mean cosine)")
        return float(interior.g) if interior.phase == HG else 0.0

    def light(self, i, light):
        from ..lights import DIRECTIONAL, POINT

        key = f"light[{i}]"
        power = np.asarray(light.intensity, dtype=np.float64)
        peak = float(power.max())
        out = {"name": key, "color": (power / peak if peak > 0.0 else np.ones(3)).tolist(),
               "intensity": peak * LUMENS_PER_WATT}
        node = {"name": key, "extensions": {"KHR_lights_punctual": {"light": len(self.lights_out())}}}
        if light.kind != DIRECTIONAL:
            node["translation"] = np.asarray(light.position, dtype=np.float64).tolist()
        if light.kind == POINT:
            out["type"] = "point"
        else:
            node["rotation"] = matrix_quaternion(_look_rotation(light.axis))
            out["type"] = "directional" if light.kind == DIRECTIONAL else "spot"
        if out["type"] == "spot":
            out["spot"] = self.cone(i, light)
        self.lights_out().append(out)
        self.doc["nodes"].append(node)
        self.used.add("KHR_lights_punctual")

    def lights_out(self) -> list:
        return self.doc.setdefault("extensions", {}).setdefault("KHR_lights_punctual", {"lights": []})["lights"]

    def cone(self, i, light) -> dict:
        key = f"light[{i}]"
        outer, inner = math.acos(min(1.0, light.cos_end)), math.acos(min(1.0, light.cos_start))
        if outer > math.pi / 2:
            self.fail(f"{key}.cone_angle", f"{math.degrees(outer):g} degrees: glTF spots open at most 90 degrees",
                      "use cone_angle <= 90")
        falloff = self.raw["light"][i].get("falloff", "smoothstep")
        if falloff != "gltf":
            self.approximated(f"{key}.falloff", f'"{falloff}" spot falloff', 'use falloff = "gltf"',
                              "glTF's falloff over the same angles")
        if not inner < outer:
            self.approximated(f"{key}.falloff_start", "a hard-edged cone (falloff_start = cone_angle)",
                              "use falloff_start < cone_angle", "innerConeAngle 1e-6 below outerConeAngle")
            inner = outer * (1.0 - 1e-6)
        return {"innerConeAngle": inner, "outerConeAngle": outer}

    def camera(self, scene):
        cam = scene.camera
        forward = cam.look_at - cam.position
        extent = float(np.max(np.abs(cam.position))) + float(np.linalg.norm(forward))
        self.doc["cameras"] = [{"name": "camera", "type": "perspective", "extras": {
            "width": cam.width, "height": cam.height, "spp": cam.spp}, "perspective": {
            "yfov": math.radians(cam.fov), "aspectRatio": cam.width / cam.height, "znear": 1e-4 * extent}}]
        self.doc["nodes"].append({"name": "camera", "camera": 0, "translation": cam.position.tolist(),
                                  "rotation": matrix_quaternion(_look_rotation(forward, cam.up))})

    def accessor(self, array: np.ndarray, kind: str, minmax=False) -> int:
        while len(self.blob) % 4:
            self.blob.append(0)
        data = np.ascontiguousarray(array).astype(array.dtype.newbyteorder("<")).tobytes()
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data)})
        self.blob += data
        a = {"bufferView": len(self.doc["bufferViews"]) - 1, "count": len(array), "type": kind,
             "componentType": {np.dtype(np.float32): 5126, np.dtype(np.uint32): 5125}[array.dtype]}
        if minmax:  # required for POSITION
            a.update(min=array.min(axis=0).tolist(), max=array.max(axis=0).tolist())
        self.doc["accessors"].append(a)
        return len(self.doc["accessors"]) - 1

    def save(self) -> list[Path]:
        while len(self.blob) % 4:
            self.blob.append(0)
        if self.out.suffix.lower() == ".glb":
            self.doc["buffers"] = [{"byteLength": len(self.blob)}]
            text = json.dumps(self.doc, allow_nan=False).encode()
            text += b" " * (-len(text) % 4)
            data = b"".join([struct.pack("<4sII", GLB_MAGIC, 2, 12 + 8 + len(text) + 8 + len(self.blob)),
                             struct.pack("<II", len(text), JSON_CHUNK), text,
                             struct.pack("<II", len(self.blob), BIN_CHUNK), bytes(self.blob)])
            files = {self.out: data}
        else:
            binary = self.out.with_suffix(".bin")
            self.doc["buffers"] = [{"byteLength": len(self.blob), "uri": binary.name}]
            files = {binary: bytes(self.blob), self.out: json.dumps(self.doc, indent=1, allow_nan=False).encode()}
        parts = {path: path.with_name(path.name + ".part") for path in files}
        try:  # every file complete, or none written
            for path, data in files.items():
                parts[path].write_bytes(data)
        except OSError as exc:
            for part in parts.values():
                part.unlink(missing_ok=True)
            raise UserError(f"{self.out}: cannot write ({exc.strerror}); check the folder and its permissions") from None
        for path, part in parts.items():
            part.replace(path)
        return list(files)
