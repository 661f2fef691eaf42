"""`render.py assets` / `raytrace.assets()` against a local HTTP server serving archives made here
(no network): download, pinned sums checked, a wrong sum or a failed download refused in one line
with nothing left on disk, unpinned archives only on request, RAYTRACE_ASSETS and the user's data
folder honoured, the bundled scenes' meshes made by the conversions, and the missing-mesh error."""
from __future__ import annotations

import gzip
import hashlib
import http.server
import os
import sys
import threading
import tomllib
import zipfile
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np
import pytest
import trimesh

import raytrace
from raytrace.cli import main
from raytrace.errors import UserError
from raytrace.scene.assets import bundled_scenes
from raytrace.scene.catalogue import ARCHIVES, NOT_DOWNLOADED
from raytrace.scene.meshes import scene_triangles

from .test_cli_errors import check_one_line

# --- fixture archives ---------------------------------------------------------------------------------------

# A cathedral in miniature: two stone quads (one written with negative indices) and one clear pane
# (material staklo) between them, with texture coordinates and normals as McGuire's file has.
SIBENIK_OBJ = """# 3ds Max Wavefront OBJ Exporter
mtllib sibenik.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 2
v 1 0 2
v 1 1 2
vt 0 0
vt 1 0
vt 1 1
vn 0 0 1
g stone
usemtl kamen_zid
f 1/1/1 2/2/1 3/3/1 4/3/1
g window
usemtl staklo
f 5/1/1 6/2/1 7/3/1
g stone
usemtl kamen_zid
v 0 0 5
v 1 0 5
v 1 1 5
v 0 1 5
f -4//1 -3//1 -2//1 -1//1
"""
SIBENIK_MTL = "newmtl kamen_zid\nKd 0.6 0.5 0.4\nnewmtl staklo\nKd 0.1 0.1 0.1\nd 0\n"

CONFERENCE_PBRT = """# a pbrt-v2 export in the LBL conference room's subset
Scale -1 1 1
LookAt 0 0 0  1 0 0  0 0 1
Camera "perspective" "float fov" [ 40 ]
WorldBegin
  MakeNamedMaterial "wall" "string type" [ "matte" ] "color Kd" [ 0.5 0.25 0.125 ]
  MakeNamedMaterial "lum" "string type" [ "matte" ] "color Kd" [ 1.0 1.0 1.0 ]
  MakeNamedMaterial "shiny" "string type" [ "plastic" ] "color Kd" [ 0.2 0.2 0.2 ]
    "color Ks" [ 0.1 0.1 0.1 ] "float roughness" [ 0.05 ]
  MakeNamedMaterial "glass" "string type" [ "glass" ] "float index" [ 1.5 ] "color Kr" [ 1 1 1 ]
    "color Kt" [ 0.9 0.9 0.9 ]
  MakeNamedMaterial "chrome" "string type" [ "mirror" ] "color Kr" [ 0.7 0.7 0.7 ]
  AttributeBegin
    Transform [ 1 0 0 0  0 1 0 0  0 0 1 0  0 0 0 1 ]
    NamedMaterial "wall"
    Shape "trianglemesh" "point P" [ 0 0 0  4 0 0  4 3 0  0 3 0 ] "integer indices" [ 0 1 2  0 2 3 ]
      "normal N" [ 0 0 1  0 0 1  0 0 1  0 0 1 ]
  AttributeEnd
  AttributeBegin
    Transform [ 1 0 0 0  0 1 0 0  0 0 1 0  1 1 0 1 ]
    NamedMaterial "lum"
    AreaLightSource "area" "color L" [ 1.5499999523162842 1.5499999523162842 1.5499999523162842 ]
    Shape "cylinder" "float radius" [ 0.5 ] "float zmin" [ 0 ] "float zmax" [ 2 ] "float phimax" [ 360 ]
  AttributeEnd
  AttributeBegin
    Transform [ 2 0 0 0  0 2 0 0  0 0 2 0  2 2 1 1 ]
    NamedMaterial "shiny"
    Shape "disk" "float height" [ 0 ] "float innerradius" [ 0.0 ] "float radius" [ 0.25 ] "float phimax" [ 360 ]
  AttributeEnd
  AttributeBegin
    Transform [ 1 0 0 0  0 1 0 0  0 0 1 0  3 2 1 1 ]
    NamedMaterial "glass"
    Shape "disk" "float height" [ 0 ] "float innerradius" [ 0.2 ] "float radius" [ 0.4 ] "float phimax" [ 360 ]
  AttributeEnd
  AttributeBegin
    Transform [ 0.5 0 0 0  0 0.5 0 0  0 0 0.5 0  1 2 2 1 ]
    NamedMaterial "chrome"
    Shape "sphere" "float radius" [ 0.6 ] "float zmin" [ -0.6 ] "float zmax" [ 0.6 ] "float phimax" [ 360 ]
  AttributeEnd
  AttributeBegin
    Transform [ -0.5 0 0 0  0 0.5 0 0  0 0 0.5 0  3 1 2 1 ]
    NamedMaterial "chrome"
    Shape "sphere" "float radius" [ 0.6 ] "float zmin" [ -0.6 ] "float zmax" [ 0.6 ] "float phimax" [ 360 ]
  AttributeEnd
  AttributeBegin
    Transform [ -1 0 0 0  0 1 0 0  0 0 1 0  3 0 0 1 ]
    NamedMaterial "wall"
    Shape "cylinder" "float radius" [ 0.5 ] "float zmin" [ 0 ] "float zmax" [ 1 ] "float phimax" [ 360 ]
  AttributeEnd
WorldEnd
"""
# trianglemesh 2, cylinders 2 x 32, disk 16, annulus 32, spheres 2 x 8 x 16 x 2
CONFERENCE_TRIANGLES = 2 + 64 + 16 + 32 + 512
POLE_TRIANGLES = 2 * 2 * 16  # a sphere's triangles at its poles have zero area: a scene leaves them out


def sibenik_zip(path: Path, obj: str = SIBENIK_OBJ, top: str = "") -> Path:
    with zipfile.ZipFile(path, "w") as z:
        z.writestr(f"{top}sibenik.obj", obj)
        z.writestr(f"{top}sibenik.mtl", SIBENIK_MTL)
        z.writestr(f"{top}copyright.txt", "Sibenik by Marko Dabrovic\n")
        z.writestr(f"{top}kamen.png", b"\x89PNG not really")
        if top:  # what macOS's zip tool adds beside the folder
            z.writestr(f"__MACOSX/{top}._sibenik.obj", b"resource fork")
    return path


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def served(tmp_path):
    """A local HTTP server over a folder holding the fixture archives: (base URL, folder)."""
    folder = tmp_path / "server"
    folder.mkdir()
    sibenik_zip(folder / "sibenik.zip")
    (folder / "conference_room.pbrt.gz").write_bytes(gzip.compress(CONFERENCE_PBRT.encode()))

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), partial(Quiet, directory=str(folder)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}", folder
    server.shutdown()
    server.server_close()


def pinned(folder: Path) -> list:
    """The catalogue's archives with the fixture archives' sums pinned."""
    return [replace(ARCHIVES["sibenik"], sha256=sha256(folder / "sibenik.zip")),
            replace(ARCHIVES["conference"], sha256=sha256(folder / "conference_room.pbrt.gz"))]


def files_under(path: Path) -> list[Path]:
    return sorted(p for p in path.rglob("*") if p.is_file()) if path.exists() else []


def by_material(path: Path) -> dict[str, np.ndarray]:
    """trimesh's reading of an OBJ: material name -> its triangles, sorted (an independent parser)."""
    scene = trimesh.load(str(path), force="scene", process=False, group_material=True)
    out = {}
    for geom in scene.geometry.values():
        tris = np.asarray(geom.vertices)[np.asarray(geom.faces)]
        name = geom.visual.material.name
        out[name] = np.concatenate([out[name], tris]) if name in out else tris
    return {k: np.array(sorted(map(tuple, v.reshape(len(v), 9)))) for k, v in out.items()}


# --- download, sums, folders --------------------------------------------------------------------------------

def test_download_checks_sums_converts_and_honours_raytrace_assets(served, tmp_path, monkeypatch):
    url, folder = served
    first, second = tmp_path / "first", tmp_path / "second"
    monkeypatch.setenv("RAYTRACE_ASSETS", os.pathsep.join([str(first), str(second)]))
    lines = []
    files = raytrace.assets(mirror=url, archives=pinned(folder), progress=False, note=lines.append)
    expected = [first / f for a in ARCHIVES.values() for f in a.files]
    assert files == expected and all(f.is_file() for f in files)
    assert not second.exists()
    assert sorted(p.name for p in (first / "archives").iterdir()) == ["conference_room.pbrt.gz", "sibenik.zip"]
    assert not [p for p in first.iterdir() if p.name.startswith(".")], "the staging folder is removed"
    text = "\n".join(lines)
    for a in ARCHIVES.values():
        assert a.credit in text and a.licence in text
    for name in ("sibenik", "conference"):
        assert ARCHIVES[name].credit in (first / ARCHIVES[name].folder / "CREDITS.txt").read_text(encoding="utf-8")
    # the bundled scenes load the converted files: stone 2 quads -> 4 triangles and the pane
    assert len(scene_triangles(raytrace.load("sibenik"))[0]) == 4 + 1
    assert len(scene_triangles(raytrace.load("conference"))[0]) == CONFERENCE_TRIANGLES - POLE_TRIANGLES
    # a second run finds them and fetches nothing (the server is not asked: a dead mirror is fine)
    again = []
    assert raytrace.assets(mirror="http://127.0.0.1:9", archives=pinned(folder), progress=False,
                           note=again.append) == expected
    assert all("already in" in line for line in again) and len(again) == 2


def test_default_folder_is_the_user_data_folder(served, tmp_path, monkeypatch):
    if not sys.platform.startswith("linux"):
        pytest.skip("XDG_DATA_HOME places the data folder on Linux only")
    url, folder = served
    monkeypatch.delenv("RAYTRACE_ASSETS", raising=False)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    raytrace.assets(["conference"], mirror=url, archives=pinned(folder), progress=False, note=lambda _: None)
    data = tmp_path / "xdg" / "raytrace-media"
    assert (data / "conference_lbl" / "conference_lbl.obj").is_file()
    assert len(scene_triangles(raytrace.load("conference"))[0]) == CONFERENCE_TRIANGLES - POLE_TRIANGLES  # found


def test_wrong_sum_refused_in_one_line_leaving_nothing(served, tmp_path, capsys):
    """The catalogue's real conference sum against the fixture archive: refused, nothing on disk."""
    url, folder = served
    target = tmp_path / "assets"
    assert main(["assets", "conference", "--folder", str(target), "--mirror", url]) == 2
    line = check_one_line(capsys.readouterr().err, "SHA-256", sha256(folder / "conference_room.pbrt.gz"),
                          ARCHIVES["conference"].sha256, "refused")
    assert "nothing was kept" in line
    assert not target.exists()


def test_wrong_sum_keeps_an_existing_folder_as_it_was(served, tmp_path):
    url, folder = served
    target = tmp_path / "assets"
    (target / "mine").mkdir(parents=True)
    (target / "mine" / "own.obj").write_text("v 0 0 0\n")
    wrong = replace(pinned(folder)[1], sha256="0" * 64)
    with pytest.raises(UserError, match="is not the pinned 0{64}"):
        raytrace.assets(["conference"], folder=target, mirror=url, archives=[wrong], progress=False)
    assert files_under(target) == [target / "mine" / "own.obj"]
    assert sorted(p.name for p in target.iterdir()) == ["mine"]


def test_offline_says_where_to_put_the_archive(served, tmp_path, capsys):
    url, folder = served
    target = tmp_path / "assets"
    dead = "http://127.0.0.1:9"  # the discard port: nothing listens there
    assert main(["assets", "conference", "--folder", str(target), "--mirror", dead]) == 2
    placed = target / "archives" / "conference_room.pbrt.gz"
    check_one_line(capsys.readouterr().err, "cannot download", f"{dead}/conference_room.pbrt.gz", str(placed))
    assert not target.exists()
    # the archive put there by hand is used as it is, its sum checked, with no network
    placed.parent.mkdir(parents=True)
    placed.write_bytes((folder / "conference_room.pbrt.gz").read_bytes())
    raytrace.assets(["conference"], folder=target, mirror=dead, archives=pinned(folder), progress=False,
                    note=lambda _: None)
    assert (target / "conference_lbl" / "conference_lbl.obj").is_file()


def test_missing_archive_on_the_server(served, tmp_path):
    url, folder = served
    (folder / "sibenik.zip").unlink()
    with pytest.raises(UserError, match=r"cannot download .*sibenik\.zip \(HTTP 404\)"):
        raytrace.assets(["sibenik"], folder=tmp_path / "a", mirror=url, trust_unpinned=True, progress=False)
    assert not (tmp_path / "a").exists()


def test_unpinned_archive_only_on_request(served, tmp_path, capsys):
    """The catalogue's Sibenik archive has no pinned sum: refused before any download, unless trusted;
    then its sum is printed."""
    url, folder = served
    target = tmp_path / "assets"
    assert main(["assets", "--folder", str(target), "--mirror", url]) == 2
    check_one_line(capsys.readouterr().err, "sibenik", "no pinned SHA-256", "--trust-unpinned")
    assert not target.exists()
    lines = []
    raytrace.assets(["sibenik"], folder=target, mirror=url, trust_unpinned=True, progress=False, note=lines.append)
    assert any(sha256(folder / "sibenik.zip") in line and "no pinned sum" in line for line in lines)
    assert (target / "sibenik" / "sibenik_staklo.obj").is_file()


def test_folder_that_cannot_be_made(tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    assert main(["assets", "conference", "--folder", str(tmp_path / "file" / "assets")]) == 2
    check_one_line(capsys.readouterr().err, str(tmp_path / "file" / "assets"), "cannot write there", "--folder")
    assert sorted(tmp_path.iterdir()) == [tmp_path / "file"]


def test_unknown_name(tmp_path, capsys):
    assert main(["assets", "sponza", "--folder", str(tmp_path / "a")]) == 2
    check_one_line(capsys.readouterr().err, "'sponza'", "sibenik", "conference")


# --- the conversions ----------------------------------------------------------------------------------------

def convert_sibenik(tmp_path: Path, obj: str = SIBENIK_OBJ, top: str = "") -> Path:
    """A fixture zip put by hand in <tmp_path>/assets/archives, converted (its own sum pinned)."""
    zipped = sibenik_zip(tmp_path / "sibenik.zip", obj=obj, top=top)
    target = tmp_path / "assets"
    (target / "archives").mkdir(parents=True)
    (target / "archives" / "sibenik.zip").write_bytes(zipped.read_bytes())
    raytrace.assets(["sibenik"], folder=target, archives=[replace(ARCHIVES["sibenik"], sha256=sha256(zipped))],
                    progress=False, note=lambda _: None)
    return target


@pytest.mark.parametrize("top", ["", "sibenik/"])
def test_sibenik_split_keeps_every_face_with_its_material(tmp_path, top):
    """sibenik.obj keeps every face but the staklo panes, sibenik_staklo.obj holds those, as trimesh
    reads the archive's file; textures and copyright.txt are kept; the mtllib line names the .mtl
    beside them, including when the archive wraps everything in one folder (and macOS's __MACOSX)."""
    target = convert_sibenik(tmp_path, top=top)
    out = target / "sibenik"
    assert sorted(p.name for p in out.iterdir()) == ["CREDITS.txt", "copyright.txt", "kamen.png", "sibenik.mtl",
                                                     "sibenik.obj", "sibenik_staklo.obj"]
    upstream = tmp_path / "upstream"
    upstream.mkdir()
    (upstream / "sibenik.obj").write_text(SIBENIK_OBJ)
    (upstream / "sibenik.mtl").write_text(SIBENIK_MTL)
    original = by_material(upstream / "sibenik.obj")
    rest, panes = by_material(out / "sibenik.obj"), by_material(out / "sibenik_staklo.obj")
    assert set(rest) == {"kamen_zid"} and set(panes) == {"staklo"}
    np.testing.assert_array_equal(rest["kamen_zid"], original["kamen_zid"])
    np.testing.assert_array_equal(panes["staklo"], original["staklo"])
    for name in ("sibenik.obj", "sibenik_staklo.obj"):
        assert "mtllib sibenik.mtl" in (out / name).read_text().splitlines()


def test_sibenik_mtllib_of_an_exporter_is_pointed_at_the_mtl_beside_it(tmp_path):
    obj = SIBENIK_OBJ.replace("mtllib sibenik.mtl", "mtllib untitled.mtl")
    target = convert_sibenik(tmp_path, obj=obj)
    assert "mtllib sibenik.mtl" in (target / "sibenik" / "sibenik.obj").read_text().splitlines()


def test_sibenik_without_panes_is_refused_leaving_the_archive_only(tmp_path):
    with pytest.raises(UserError, match="no faces with `usemtl staklo`"):
        convert_sibenik(tmp_path, obj=SIBENIK_OBJ.replace("usemtl staklo", "usemtl kamen_zid"))
    target = tmp_path / "assets"
    assert files_under(target) == [target / "archives" / "sibenik.zip"]


def test_conference_conversion_against_the_analytic_shapes(served, tmp_path):
    """Each pbrt shape's vertices where its equation puts them (after its Transform), every closed
    shape facing out (also under a mirroring Transform), materials as pbrt gives them."""
    url, folder = served
    target = tmp_path / "assets"
    raytrace.assets(["conference"], folder=target, mirror=url, archives=pinned(folder), progress=False,
                    note=lambda _: None)
    obj = target / "conference_lbl" / "conference_lbl.obj"
    meshes = trimesh.load(str(obj), force="scene", process=False, group_material=False)
    parts = {}
    for geom in meshes.geometry.values():
        parts.setdefault(geom.visual.material.name, []).append(np.asarray(geom.vertices)[np.asarray(geom.faces)])
    tris = {k: np.concatenate(v) for k, v in parts.items()}
    assert sum(len(t) for t in tris.values()) == CONFERENCE_TRIANGLES
    lum = tris["lum"].reshape(-1, 3)
    np.testing.assert_allclose(np.hypot(lum[:, 0] - 1, lum[:, 1] - 1), 0.5, atol=1e-6)
    assert np.all(np.isin(lum[:, 2], [0.0, 2.0]))
    disk = tris["shiny"].reshape(-1, 3)  # radius 0.25 scaled by 2 around (2, 2, 1)
    r = np.hypot(disk[:, 0] - 2, disk[:, 1] - 2)
    assert np.allclose(disk[:, 2], 1) and np.allclose(r[(r > 1e-9)], 0.5, atol=1e-6)
    ring = tris["glass"].reshape(-1, 3)
    r = np.hypot(ring[:, 0] - 3, ring[:, 1] - 2)  # the file holds 6 decimals: 1e-6 apart at most
    inner, outer = np.isclose(r, 0.2, rtol=0, atol=2e-6), np.isclose(r, 0.4, rtol=0, atol=2e-6)
    assert np.all(inner | outer) and inner.any() and outer.any()
    chrome = tris["chrome"]
    centres = np.where(chrome.reshape(-1, 3)[:, :1] < 2.0, [1, 2, 2], [3, 1, 2])
    np.testing.assert_allclose(np.linalg.norm(chrome.reshape(-1, 3) - centres, axis=1), 0.3, atol=1e-6)
    for name, centre_of in (("chrome", lambda c: np.where(c[:, :1] < 2.0, [1, 2, 2], [3, 1, 2])),
                            ("lum", lambda c: np.column_stack([np.ones(len(c)), np.ones(len(c)), c[:, 2]])),
                            ("wall", None)):
        t = tris[name]
        n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        c = t.mean(axis=1)
        keep = np.linalg.norm(n, axis=1) > 1e-12  # the sphere's pole triangles are degenerate
        if centre_of is None:  # the wall quad of the trianglemesh, as written (+z) and the mirrored cylinder
            walls = t[keep & np.isclose(c[:, 2], 0.0)]
            assert len(walls) == 2
            cyl = keep & ~np.isclose(c[:, 2], 0.0)
            out = c[cyl] - np.column_stack([np.full(cyl.sum(), 3.0), np.zeros(cyl.sum()), c[cyl][:, 2]])
            assert np.all(np.einsum("ij,ij->i", n[cyl], out) > 0), "mirrored cylinder faces in"
            continue
        out = c[keep] - centre_of(c[keep])
        assert np.all(np.einsum("ij,ij->i", n[keep], out) > 0), f"{name} faces in"
    mtl = (target / "conference_lbl" / "conference_lbl.mtl").read_text()
    assert "newmtl wall\n# pbrt type: matte\nKd 0.5 0.25 0.125\n" in mtl
    assert "newmtl lum\n# pbrt type: matte\nKd 1.0 1.0 1.0\nKe 1.55 1.55 1.55\n" in mtl
    assert "newmtl shiny\n# pbrt type: plastic\nKd 0.2 0.2 0.2\nKs 0.1 0.1 0.1\n# pbrt roughness 0.05\n" in mtl
    assert "newmtl glass\n# pbrt type: glass\nKd 0 0 0\nKs 1 1 1\nTf 0.9 0.9 0.9\nNi 1.5\nd 0.2\nillum 7\n" in mtl
    assert "newmtl chrome\n# pbrt type: mirror\nKd 0 0 0\nKs 0.7 0.7 0.7\nillum 3\n" in mtl


def shared_folder(name: str, needs: str) -> Path:
    """<RAYTRACE_ASSETS folder>/name holding `needs` (../shared/scenes), or skip."""
    found = next((Path(p) / name for p in os.environ.get("RAYTRACE_ASSETS", "").split(os.pathsep)
                  if p and (Path(p) / name / needs).is_file()), None)
    if found is None:
        pytest.skip(f"needs RAYTRACE_ASSETS=../shared/scenes ({name}/{needs})")
    return found


def test_sibenik_split_of_the_whole_cathedral(tmp_path):
    """The files the scene was made with (../shared/scenes/sibenik: the cathedral without its panes,
    an exporter's `mtllib untitled.mtl` line, and the panes), joined into one OBJ as McGuire's holds
    the model, split back by `render.py assets`: each file's triangles come back, as trimesh reads
    them, and both name sibenik.mtl."""
    shared = shared_folder("sibenik", "sibenik_staklo.obj")
    cathedral = (shared / "sibenik.obj").read_text(encoding="utf-8")
    counts = {tag: sum(1 for line in cathedral.splitlines() if line.startswith(tag + " ")) for tag in ("v", "vt", "vn")}
    panes = []
    for line in (shared / "sibenik_staklo.obj").read_text(encoding="utf-8").splitlines():
        if line.startswith("f "):
            line = "f " + " ".join("/".join(str(int(i) + counts[t]) if i else "" for t, i in zip(("v", "vt", "vn"),
                                                                                                  c.split("/")))
                                   for c in line.split()[1:])
        if not line.startswith(("#", "mtllib")):
            panes.append(line)
    joined = cathedral.replace("mtllib sibenik.mtl", "mtllib untitled.mtl") + "\n".join(panes) + "\n"
    with zipfile.ZipFile(tmp_path / "sibenik.zip", "w") as z:
        z.writestr("sibenik.obj", joined)
        z.write(shared / "sibenik.mtl", "sibenik.mtl")
    target = tmp_path / "assets"
    (target / "archives").mkdir(parents=True)
    (target / "archives" / "sibenik.zip").write_bytes((tmp_path / "sibenik.zip").read_bytes())
    raytrace.assets(["sibenik"], folder=target, progress=False, note=lambda _: None,
                    archives=[replace(ARCHIVES["sibenik"], sha256=sha256(tmp_path / "sibenik.zip"))])
    for name in ("sibenik.obj", "sibenik_staklo.obj"):
        made, reference = by_material(target / "sibenik" / name), by_material(shared / name)
        assert made.keys() == reference.keys()
        for material in reference:
            np.testing.assert_array_equal(made[material], reference[material])
        assert "mtllib sibenik.mtl" in (target / "sibenik" / name).read_text(encoding="utf-8").splitlines()


def test_conference_conversion_reproduces_the_shared_files(tmp_path):
    """The real archive (its copy beside the repository, verified against the pinned sum) converts to
    the very files the bundled scene was made with (../shared/scenes/conference_lbl, converted by a
    separate helper): byte for byte after the header."""
    shared = shared_folder("conference_lbl", "conference_room.pbrt.gz")
    archive = shared / "conference_room.pbrt.gz"
    assert sha256(archive) == ARCHIVES["conference"].sha256
    target = tmp_path / "assets"
    (target / "archives").mkdir(parents=True)
    (target / "archives" / archive.name).symlink_to(archive)
    raytrace.assets(["conference"], folder=target, progress=False, note=lambda _: None)
    made = (target / "conference_lbl" / "conference_lbl.obj").read_bytes()
    reference = (shared / "conference_lbl.obj").read_bytes()
    assert made[made.index(b"mtllib"):] == reference[reference.index(b"mtllib"):]
    assert (target / "conference_lbl" / "conference_lbl.mtl").read_bytes() == (shared / "conference_lbl.mtl").read_bytes()


# --- the catalogue and the missing-mesh error ---------------------------------------------------------------

def test_catalogue_covers_the_bundled_scenes_meshes():
    provided = {f for a in ARCHIVES.values() for f in a.files} | set(NOT_DOWNLOADED)
    for name in ("sibenik", "conference", "bridge"):
        raw = tomllib.loads(bundled_scenes()[name].read_text(encoding="utf-8"))
        meshes = [s["mesh"] for s in raw["shape"] if "mesh" in s]
        assert meshes and set(meshes) <= provided, (name, meshes)
    for a in ARCHIVES.values():
        assert a.url.startswith("https://") and a.filename
        assert a.sha256 is None or (len(a.sha256) == 64 and int(a.sha256, 16) >= 0)


@pytest.mark.parametrize("scene, fragments", [
    ("sibenik", ["sibenik/sibenik.obj", "`render.py assets sibenik` downloads it into", "docs/assets.md"]),
    ("conference", ["conference_lbl/conference_lbl.obj", "`render.py assets conference` downloads it into"]),
    ("bridge", ["bridge/bridge_viaduct.glb", "does not fetch it", "docs/assets.md#the-bridge", "RAYTRACE_ASSETS"]),
])
def test_missing_paper_mesh_names_render_py_assets(scene, fragments, tmp_path, monkeypatch, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    monkeypatch.setenv("RAYTRACE_ASSETS", str(empty))
    assert main(["describe", scene]) == 2
    check_one_line(capsys.readouterr().err, *fragments, str(empty))


def test_missing_own_mesh_names_the_folders_not_render_py_assets(tmp_path, monkeypatch, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    monkeypatch.setenv("RAYTRACE_ASSETS", str(empty))
    scene = tmp_path / "mine.toml"
    scene.write_text('[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n[[shape]]\nmesh = "statue.obj"\n')
    assert main(["describe", str(scene)]) == 2
    line = check_one_line(capsys.readouterr().err, "statue.obj", str(tmp_path), str(empty), "RAYTRACE_ASSETS")
    assert "render.py assets" not in line
