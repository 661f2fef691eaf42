"""User errors on the command line (SCENE_FORMAT.md, "Command line"): one line on stderr that names the
file, the key and the fix; a non-zero exit status; no traceback; no output file left behind.

Most cases call `raytrace.cli.main([...])` in-process (fast); a few run `render.py` as a subprocess
to prove the exit status and the absence of a traceback end to end.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from raytrace.cli import main

REPO = Path(__file__).resolve().parents[1]
IS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0

BASE = """\
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov = 60.0
width = 4
height = 3
spp = 1

[[shape]]
primitive = "box"
min = [-5.0, -5.0, -5.0]
max = [5.0, 5.0, 5.0]

[[light]]
position = [1.0, 0.5, 0.0]
intensity = [10.0, 10.0, 10.0]

[medium]
sigma_a = [0.05, 0.05, 0.05]
sigma_s = [0.15, 0.15, 0.15]
phase = "isotropic"

[background]
radiance = [0.0, 0.0, 0.0]
"""


def _method():
    """A registered method, so that valid scenes get past the method lookup."""
    from raytrace.methods import registry

    names = list(registry())
    return "analytic" if "analytic" in names else names[0]


def edit(old, new, text=BASE):
    assert text.count(old) == 1, f"test bug: {old!r} not found exactly once"
    return text.replace(old, new)


@pytest.fixture
def work(tmp_path):
    """A scene folder and an (empty) output folder."""
    (tmp_path / "scenes").mkdir()
    (tmp_path / "out").mkdir()
    return tmp_path


def write_scene(work, text, name="scene.toml"):
    p = work / "scenes" / name
    p.write_text(text)
    return p


def render_argv(work, scene, *extra, method=True):
    argv = ["render", str(scene), "--out", str(work / "out" / "img.exr"), "--png", str(work / "out" / "img.png"),
            "--width", "4", "--height", "3", "--quiet"]
    if method:
        argv += ["--method", _method()]
    return argv + list(extra)


def check_one_line(err, *fragments):
    """The stderr of a failed command: exactly one line, no traceback, containing every fragment,
    and a fix after the problem ("problem; fix")."""
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, f"expected one line on stderr, got {len(lines)}:\n{err}"
    assert err.endswith("\n")
    line = lines[0]
    assert line.startswith("error: ")
    for f in fragments:
        assert f in line, f"{f!r} missing from: {line}"
    assert "; " in line, f"no fix in: {line}"
    fix = line.rsplit("; ", 1)[1]
    assert len(fix.split()) >= 2, f"fix too short in: {line}"
    return line


def check_nothing_written(work):
    out = work / "out"
    assert not (out / "img.exr").exists()
    assert not (out / "img.png").exists()
    assert sorted(os.listdir(out)) == [], "temporary or partial files left behind"


def run_inprocess(argv, capsys):
    rc = main(argv)
    cap = capsys.readouterr()
    assert rc != 0 and rc is not None
    return cap.err


# --- scene-file errors -------------------------------------------------------------------------------------

# (id, scene text, the key the message must name, a fragment of the fix)
SCENE_CASES = [
    ("malformed-toml", edit("fov = 60.0", "fov = = 60.0"), "line 4", "malformed TOML"),
    ("unclosed-array", edit("max = [5.0, 5.0, 5.0]", "max = [5.0, 5.0, 5.0"), "line", "malformed TOML"),
    ("unknown-top-level", "colour = 1\n" + BASE, "colour", "allowed keys"),
    ("misspelt-top-level-table", BASE.replace("[[light]]", "[[lights]]"), "lights", 'did you mean "light"'),
    ("sigma_t-in-medium", edit("sigma_s = [0.15, 0.15, 0.15]", "sigma_t = 0.2"), "medium.sigma_t",
     'did you mean "sigma_s"'),
    ("sigmas-in-medium", edit("sigma_s = [0.15, 0.15, 0.15]", "sigmas = 0.15"), "medium.sigmas",
     'did you mean "sigma_s"'),
    ("postion-in-camera", edit("position = [0.0, 0.0, 4.0]", "position = [0.0, 0.0, 4.0]\npostion = [1.0, 0.0, 0.0]"),
     "camera.postion", 'did you mean "position"'),
    ("intensty-in-light", edit("intensity = [10.0, 10.0, 10.0]", "intensity = 1.0\nintensty = 10.0"),
     "light[0].intensty", 'did you mean "intensity"'),
    ("reflectence-in-shape", edit('primitive = "box"', 'primitive = "box"\nreflectence = 0.5'),
     "shape[0].reflectence", 'did you mean "reflectance"'),
    ("fov-string", edit("fov = 60.0", 'fov = "60"'), "camera.fov", "write a number"),
    ("sigma_s-string", edit("sigma_s = [0.15, 0.15, 0.15]", 'sigma_s = "thick"'), "medium.sigma_s", "write a number"),
    ("position-2-vector", edit("position = [0.0, 0.0, 4.0]", "position = [0.0, 4.0]"), "camera.position",
     "three numbers"),
    ("light-position-string", edit("position = [1.0, 0.5, 0.0]", 'position = "here"'), "light[0].position",
     "three numbers"),
    ("width-float", edit("width = 4", "width = 4.0"), "camera.width", "whole number"),
    ("spp-bool", edit("spp = 1", "spp = true"), "camera.spp", "write a number"),
    ("colour-2-channels", edit("sigma_a = [0.05, 0.05, 0.05]", "sigma_a = [0.05, 0.05]"), "medium.sigma_a",
     "three numbers or one"),
    ("sigma_a-negative", edit("sigma_a = [0.05, 0.05, 0.05]", "sigma_a = -0.1"), "medium.sigma_a", "at least 0"),
    ("sigma_a-channel-negative", edit("sigma_a = [0.05, 0.05, 0.05]", "sigma_a = [0.05, -0.1, 0.05]"),
     "medium.sigma_a[1]", "at least 0"),
    ("sigma_s-inf", edit("sigma_s = [0.15, 0.15, 0.15]", "sigma_s = inf"), "medium.sigma_s", "finite"),
    ("sigma_s-minus-inf", edit("sigma_s = [0.15, 0.15, 0.15]", "sigma_s = -inf"), "medium.sigma_s", "finite"),
    ("sigma_s-nan", edit("sigma_s = [0.15, 0.15, 0.15]", "sigma_s = nan"), "medium.sigma_s", "finite"),
    ("intensity-negative", edit("intensity = [10.0, 10.0, 10.0]", "intensity = -1.0"), "light[0].intensity",
     "at least 0"),
    ("intensity-nan-channel", edit("intensity = [10.0, 10.0, 10.0]", "intensity = [10.0, nan, 10.0]"),
     "light[0].intensity[1]", "finite"),
    ("intensity-inf", edit("intensity = [10.0, 10.0, 10.0]", "intensity = inf"), "light[0].intensity", "finite"),
    ("background-negative", edit("radiance = [0.0, 0.0, 0.0]", "radiance = -1.0"), "background.radiance",
     "at least 0"),
    ("position-nan", edit("position = [0.0, 0.0, 4.0]", "position = [0.0, nan, 4.0]"), "camera.position[1]",
     "finite"),
    ("width-zero", edit("width = 4", "width = 0"), "camera.width", "greater than 0"),
    ("height-negative", edit("height = 3", "height = -3"), "camera.height", "greater than 0"),
    ("spp-zero", edit("spp = 1", "spp = 0"), "camera.spp", "greater than 0"),
    ("fov-180", edit("fov = 60.0", "fov = 180.0"), "camera.fov", "field of view"),
    ("look_at-equals-position", edit("look_at = [0.0, 0.0, 0.0]", "look_at = [0.0, 0.0, 4.0]"), "camera.look_at",
     "look at a point away"),
    ("up-parallel", edit("fov = 60.0", "up = [0.0, 0.0, 1.0]\nfov = 60.0"), "camera.up", "not along"),
    ("up-antiparallel", edit("fov = 60.0", "up = [0.0, 0.0, -3.0]\nfov = 60.0"), "camera.up", "not along"),
    ("up-zero", edit("fov = 60.0", "up = [0.0, 0.0, 0.0]\nfov = 60.0"), "camera.up", "up vector"),
    ("g-one", edit('phase = "isotropic"', 'phase = { type = "hg", g = 1.0 }'), "medium.phase.g", "-1 < g < 1"),
    ("g-minus-1.5", edit('phase = "isotropic"', 'phase = { type = "hg", g = -1.5 }'), "medium.phase.g", "-1 < g < 1"),
    ("g-nan", edit('phase = "isotropic"', 'phase = { type = "hg", g = nan }'), "medium.phase.g", "finite"),
    ("hg-string-without-g", edit('phase = "isotropic"', 'phase = "hg"'), "medium.phase", "g = 0.5"),
    ("hg-table-without-g", edit('phase = "isotropic"', 'phase = { type = "hg" }'), "medium.phase.g", "add g"),
    ("phase-misspelt", edit('phase = "isotropic"', 'phase = "isotropc"'), "medium.phase", 'did you mean "isotropic"'),
    ("g-with-isotropic", edit('phase = "isotropic"', 'phase = { type = "isotropic", g = 0.3 }'), "medium.phase.g",
     "remove g"),
    ("primitive-unknown", edit('primitive = "box"', 'primitive = "boxx"'), "shape[0].primitive", 'did you mean "box"'),
    ("box-min-above-max", edit("max = [5.0, 5.0, 5.0]", "max = [5.0, -6.0, 5.0]"), "shape[0].max", "fix min and max"),
    ("reflectance-above-1", edit('primitive = "box"', 'primitive = "box"\nreflectance = 1.5'), "shape[0].reflectance",
     "[0, 1]"),
    ("mesh-and-primitive", edit('primitive = "box"', 'primitive = "box"\nmesh = "a.obj"'), "shape[0]", "exactly one"),
    ("transform-scale-zero", edit('primitive = "box"', 'primitive = "box"\ntransform = { scale = 0.0 }'),
     "shape[0].transform.scale", "non-zero"),
    ("transform-misspelt", edit('primitive = "box"', 'primitive = "box"\ntransform = { rotation = [0.0, 1.0, 0.0] }'),
     "shape[0].transform.rotation", 'did you mean "rotate"'),
    ("camera-missing", BASE.split("[[shape]]", 1)[1].join(["[[shape]]", ""]), "camera", "add a [camera]"),
    ("render-method-unknown", BASE + '\n[render]\nmethod = "no-such-method"\n', "render.method", "choose one of"),
    ("render-seed-negative", BASE + "\n[render]\nseed = -1\n", "render.seed", "at least 0"),
]


@pytest.mark.parametrize("text,key,fix", [c[1:] for c in SCENE_CASES], ids=[c[0] for c in SCENE_CASES])
def test_scene_errors(work, capsys, text, key, fix):
    scene = write_scene(work, text)
    err = run_inprocess(render_argv(work, scene), capsys)
    check_one_line(err, str(scene), key, fix)
    check_nothing_written(work)


def test_the_base_scene_is_valid(work, capsys):
    """Guards the cases above: without the edit, the same scene renders."""
    scene = write_scene(work, BASE)
    assert main(render_argv(work, scene)) == 0
    assert (work / "out" / "img.exr").is_file() and (work / "out" / "img.png").is_file()
    assert capsys.readouterr().err == ""


def test_describe_reports_the_same_errors(work, capsys):
    scene = write_scene(work, edit("sigma_s = [0.15, 0.15, 0.15]", "sigmas = 0.15"))
    err = run_inprocess(["describe", str(scene)], capsys)
    check_one_line(err, str(scene), "medium.sigmas", 'did you mean "sigma_s"')


# --- command-line flags ------------------------------------------------------------------------------------

FLAG_CASES = [
    ("width-0", ["--width", "0"], "--width"),
    ("height-0", ["--height", "0"], "--height"),
    ("spp-0", ["--spp", "0"], "--spp"),
    ("spp-negative", ["--spp", "-4"], "--spp"),
    ("threads-0", ["--threads", "0"], "--threads"),
    ("seed-negative", ["--seed", "-1"], "--seed"),
    ("method-unknown", ["--method", "no-such-method"], "--method no-such-method"),
]


@pytest.mark.parametrize("flags,key", [c[1:] for c in FLAG_CASES], ids=[c[0] for c in FLAG_CASES])
def test_flag_errors(work, capsys, flags, key):
    scene = write_scene(work, BASE)
    err = run_inprocess(render_argv(work, scene) + flags, capsys)
    line = check_one_line(err, key)
    if key.startswith("--method"):
        assert _method() in line  # the fix lists the methods that exist
    check_nothing_written(work)


@pytest.mark.parametrize("flags,fragment", [
    (["--width", "4.5"], "--width"),
    (["--spp", "many"], "--spp"),
    (["--no-such-flag"], "--no-such-flag"),
])
def test_argparse_errors_are_one_line(work, capsys, flags, fragment):
    scene = write_scene(work, BASE)
    with pytest.raises(SystemExit) as exc:
        main(render_argv(work, scene) + flags)
    assert exc.value.code not in (0, None)
    check_one_line(capsys.readouterr().err, fragment, "--help")
    check_nothing_written(work)


SET_CASES = [
    ("no-equals", "medium.sigma_s", "--set medium.sigma_s", "key.path=value"),
    ("empty-key", "=0.2", "--set =0.2", "for example"),
    ("empty-segment", "medium..sigma_s=0.2", "--set medium..sigma_s", "for example"),
    ("misspelt-leaf", "medium.sigmas=0.2", "medium.sigmas", 'did you mean "sigma_s"'),
    ("unknown-top", "fog.sigma_s=0.2", "fog", "allowed keys"),
    ("shape-index-out-of-range", "shape.3.reflectance=0.2", "--set shape[3].reflectance", "1 entry; index it as shape[0]"),
    ("shape-index-not-a-number", "shape.first.reflectance=0.2", "--set shape.first.reflectance", "index it as shape[0]"),
    ("vector-component-by-name", "camera.position.x=1.0", "--set camera.position.x", "0..2"),
    ("into-a-number", "camera.fov.x=1.0", "--set camera.fov.x", "set it as a whole"),
    ("into-a-vector", "medium.sigma_s.r=0.2", "--set medium.sigma_s.r", "0..2"),
    ("bracket-index-out-of-range", "shape[3].reflectance=0.2", "--set shape[3].reflectance", "1 entry; index it as shape[0]"),
    ("bracket-not-closed", "shape[0.reflectance=0.2", "malformed key 'shape[0.reflectance'", "light[1].intensity"),
    ("bracket-not-a-number", "shape[a].reflectance=0.2", "malformed key", "in brackets"),
    ("index-of-a-table", "medium[0].sigma_s=0.2", "--set medium[0].sigma_s", "not an array"),
    ("bad-value", "medium.sigma_s=-1", "medium.sigma_s", "at least 0"),
    ("bad-g", 'medium.phase={type="hg",g=1.5}', "medium.phase.g", "-1 < g < 1"),
]


@pytest.mark.parametrize("override,key,fix", [c[1:] for c in SET_CASES], ids=[c[0] for c in SET_CASES])
def test_set_errors(work, capsys, override, key, fix):
    scene = write_scene(work, BASE)
    err = run_inprocess(render_argv(work, scene, "--set", override), capsys)
    check_one_line(err, str(scene), key, fix)
    check_nothing_written(work)


def test_set_on_a_scene_without_lights(work, capsys):
    scene = write_scene(work, BASE.split("[[light]]")[0] + "[medium]\nsigma_s = 0.1\n")
    err = run_inprocess(render_argv(work, scene, "--set", "light.0.intensity=1.0"), capsys)
    check_one_line(err, str(scene), "--set light[0].intensity", "add one")


def test_nonexistent_scene_file(work, capsys):
    missing = work / "scenes" / "nope.toml"
    err = run_inprocess(render_argv(work, missing), capsys)
    check_one_line(err, str(missing), "no such scene file", "check the path")
    check_nothing_written(work)


def test_scene_file_that_is_a_folder(work, capsys):
    err = run_inprocess(render_argv(work, work / "scenes"), capsys)
    check_one_line(err, str(work / "scenes"), "cannot read")


def test_scene_file_not_utf8(work, capsys):
    scene = work / "scenes" / "latin1.toml"
    scene.write_bytes(BASE.encode() + b'name = "caf\xe9"\n')
    err = run_inprocess(render_argv(work, scene), capsys)
    check_one_line(err, str(scene), "encoding")


# --- meshes --------------------------------------------------------------------------------------------------

def mesh_scene(work, mesh):
    return write_scene(work, BASE + f'\n[[shape]]\nmesh = "{mesh}"\n')


def test_missing_mesh_lists_every_folder_searched(work, capsys, monkeypatch):
    a, b = work / "assets_a", work / "assets_b"
    a.mkdir(), b.mkdir()
    monkeypatch.setenv("RAYTRACE_ASSETS", os.pathsep.join([str(a), "", str(b)]))
    scene = mesh_scene(work, "sub/missing.obj")
    err = run_inprocess(render_argv(work, scene), capsys)
    line = check_one_line(err, str(scene), "shape[1].mesh", "missing.obj", "RAYTRACE_ASSETS")
    folders = [str(scene.parent), str(a), str(b)]
    positions = [line.find(f) for f in folders]
    assert all(p >= 0 for p in positions), line
    assert positions == sorted(positions), "folders must be listed in search order"
    check_nothing_written(work)


def test_missing_mesh_without_env(work, capsys, monkeypatch):
    monkeypatch.delenv("RAYTRACE_ASSETS", raising=False)
    scene = mesh_scene(work, "missing.ply")
    err = run_inprocess(render_argv(work, scene), capsys)
    check_one_line(err, str(scene), "shape[1].mesh", str(scene.parent), "RAYTRACE_ASSETS")


GARBAGE = {
    "ascii.obj": b"this is not a mesh\nreally not\n",
    "binary.obj": bytes(range(256)) * 4,
    "x.ply": b"hello\nnot a ply\n",
    "x.glb": b"glTF garbage bytes \x00\x01\x02",
}


@pytest.mark.parametrize("name", list(GARBAGE))
def test_unreadable_mesh_garbage(work, capsys, name):
    (work / "scenes" / name).write_bytes(GARBAGE[name])
    scene = mesh_scene(work, name)
    err = run_inprocess(render_argv(work, scene), capsys)
    check_one_line(err, name, "shape[1].mesh")
    check_nothing_written(work)


@pytest.mark.skipif(IS_ROOT or not hasattr(os, "geteuid"), reason="root can read any file")
def test_unreadable_mesh_no_permission(work, capsys):
    mesh = work / "scenes" / "x.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    mesh.chmod(0)
    try:
        scene = mesh_scene(work, "x.obj")
        err = run_inprocess(render_argv(work, scene), capsys)
        check_one_line(err, "x.obj", "shape[1].mesh")
        check_nothing_written(work)
    finally:
        mesh.chmod(0o644)


# --- output paths --------------------------------------------------------------------------------------------

def test_missing_output_folders_are_created_when_writing(work, capsys):
    scene = write_scene(work, BASE)
    exr, png = work / "new" / "deeper" / "img.exr", work / "other" / "img.png"
    argv = render_argv(work, scene)
    argv[argv.index("--out") + 1], argv[argv.index("--png") + 1] = str(exr), str(png)
    assert main(argv) == 0
    assert exr.is_file() and png.is_file()


def test_a_refused_render_creates_no_folder(work, capsys):
    """A refusal that comes after the output checks (the method refuses a flag) leaves no folder."""
    scene = write_scene(work, BASE)
    argv = render_argv(work, scene, "--precision", "1e-6", method=False) + ["--method", "raymarch"]
    argv[argv.index("--out") + 1] = str(work / "new" / "img.exr")
    err = run_inprocess(argv, capsys)
    check_one_line(err, "--precision", "method raymarch does not read")
    assert not (work / "new").exists()
    check_nothing_written(work)


def test_a_failed_save_removes_the_folders_it_made(work, capsys, monkeypatch):
    from raytrace.output import film

    def png_writer(rgb8):
        def write(tmp):
            raise OSError(28, "No space left on device")
        return write
    monkeypatch.setattr(film, "png_writer", png_writer)
    scene = write_scene(work, BASE)
    argv = render_argv(work, scene)
    argv[argv.index("--out") + 1] = str(work / "new" / "deeper" / "img.exr")
    err = run_inprocess(argv, capsys)
    check_one_line(err, "img.png", "No space left on device")
    assert not (work / "new").exists()
    check_nothing_written(work)


@pytest.mark.parametrize("flag", ["--out", "--png"])
def test_an_output_under_a_file_is_refused(work, capsys, flag):
    scene = write_scene(work, BASE)
    target = scene / "sub" / ("img.exr" if flag == "--out" else "img.png")
    argv = render_argv(work, scene)
    argv[argv.index(flag) + 1] = str(target)
    err = run_inprocess(argv, capsys)
    check_one_line(err, f"{flag} {target}", f"{scene} is a file, not a folder")
    check_nothing_written(work)


def test_output_path_is_a_folder(work, capsys):
    scene = write_scene(work, BASE)
    (work / "out" / "img.exr").mkdir()
    err = run_inprocess(render_argv(work, scene), capsys)
    check_one_line(err, str(work / "out" / "img.exr"), "not writable")
    assert (work / "out" / "img.exr").is_dir()
    assert sorted(os.listdir(work / "out")) == ["img.exr"]


def test_output_not_exr(work, capsys):
    scene = write_scene(work, BASE)
    argv = render_argv(work, scene)
    argv[argv.index("--out") + 1] = str(work / "out" / "img.png")
    err = run_inprocess(argv, capsys)
    check_one_line(err, "--out", "must end in .exr")
    assert os.listdir(work / "out") == []


@pytest.mark.skipif(IS_ROOT or not hasattr(os, "geteuid"), reason="root can write into read-only folders")
def test_output_folder_read_only(work, capsys):
    scene = write_scene(work, BASE)
    out = work / "out"
    out.chmod(0o555)
    try:
        err = run_inprocess(render_argv(work, scene), capsys)
        check_one_line(err, str(out / "img.exr"), "writable")
        check_nothing_written(work)
    finally:
        out.chmod(0o755)


# --- diff ----------------------------------------------------------------------------------------------------

def _exr(path, h, w, value=0.5):
    from raytrace.output import film

    film.write_exr(path, np.full((h, w, 3), value, dtype=np.float32))
    return path


def test_diff_missing_file(work, capsys):
    ref = _exr(work / "ref.exr", 3, 4)
    missing = work / "nope.exr"
    for argv in (["diff", str(missing), str(ref)], ["diff", str(ref), str(missing)]):
        err = run_inprocess(argv, capsys)
        check_one_line(err, str(missing), "no such image", "check the path")


def test_diff_different_sizes(work, capsys):
    a = _exr(work / "a.exr", 3, 4)
    b = _exr(work / "b.exr", 4, 3)
    err = run_inprocess(["diff", str(a), str(b), "--map", str(work / "out" / "map.png")], capsys)
    check_one_line(err, str(a), str(b), "4x3", "3x4", "same")
    assert os.listdir(work / "out") == []


def test_diff_garbage_image(work, capsys):
    a = _exr(work / "a.exr", 3, 4)
    bad = work / "bad.exr"
    bad.write_bytes(b"not an exr\n" * 10)
    err = run_inprocess(["diff", str(bad), str(a)], capsys)
    check_one_line(err, str(bad), "EXR")


# --- end to end: a few cases through a real process -------------------------------------------------------

def _run(argv, env_extra=None):
    env = dict(os.environ)
    env.update(env_extra or {})
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.run([sys.executable, "render.py", *argv], cwd=REPO, capture_output=True, text=True,
                          env=env, timeout=120)


SUBPROCESS_CASES = ["malformed-toml", "misspelt-key", "missing-mesh", "unwritable-output", "width-flag-zero",
                    "float-width-flag", "diff-sizes"]


@pytest.mark.parametrize("case", SUBPROCESS_CASES)
def test_subprocess_end_to_end(work, case):
    env = {}
    extra = []
    frags = []
    if case == "malformed-toml":
        scene = write_scene(work, edit("fov = 60.0", "fov = = 60.0"))
        frags = [str(scene), "malformed TOML", "line 4"]
    elif case == "misspelt-key":
        scene = write_scene(work, edit("sigma_s = [0.15, 0.15, 0.15]", "sigma_t = 0.2"))
        frags = [str(scene), "medium.sigma_t", 'did you mean "sigma_s"']
    elif case == "missing-mesh":
        extra_dir = work / "assets"
        extra_dir.mkdir()
        env["RAYTRACE_ASSETS"] = str(extra_dir)
        scene = mesh_scene(work, "missing.obj")
        frags = [str(scene), "shape[1].mesh", str(scene.parent), str(extra_dir)]
    elif case == "unwritable-output":
        scene = write_scene(work, BASE)
        frags = ["is a file, not a folder"]
    elif case == "width-flag-zero":
        scene = write_scene(work, BASE)
        extra = ["--width", "0"]
        frags = ["--width"]
    elif case == "float-width-flag":
        scene = write_scene(work, BASE)
        extra = ["--width", "2.5"]
        frags = ["--width", "2.5"]
    if case == "diff-sizes":
        a, b = _exr(work / "a.exr", 3, 4), _exr(work / "b.exr", 2, 2)
        argv = ["diff", str(a), str(b)]
        frags = [str(a), str(b)]
    else:
        argv = render_argv(work, scene, *extra)
        if case == "unwritable-output":
            argv[argv.index("--out") + 1] = str(scene / "img.exr")  # under the scene file
    proc = _run(argv, env)
    assert proc.returncode != 0, proc.stderr
    assert proc.stdout == ""
    check_one_line(proc.stderr, *frags)
    check_nothing_written(work)


# --- the permission cases again, simulated, so that they also run as root -------------------------------------

def test_read_only_output_folder_simulated(work, capsys, monkeypatch):
    scene = write_scene(work, BASE)
    out = str(work / "out")
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, *a, **k: False if (str(p) == out and mode & os.W_OK)
                        else real_access(p, mode, *a, **k))
    err = run_inprocess(render_argv(work, scene), capsys)
    check_one_line(err, str(work / "out" / "img.exr"), "not writable", "writable output path")
    check_nothing_written(work)


def test_unreadable_mesh_simulated(work, capsys, monkeypatch):
    import trimesh

    mesh = work / "scenes" / "x.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")

    def denied(path, *a, **k):
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(trimesh, "load", denied)
    scene = mesh_scene(work, "x.obj")
    err = run_inprocess(render_argv(work, scene), capsys)
    check_one_line(err, str(mesh), "shape[1].mesh", "Permission denied")
    check_nothing_written(work)


@pytest.mark.parametrize("flag, path", [("--png", "/proc/a.png"), ("--checkpoint", "/proc/c.ckpt.npz")])
def test_an_unwritable_preview_or_checkpoint_is_named_before_rendering(work, capsys, flag, path):
    """A path whose folder exists but takes no file (/proc, even for root): one line naming the flag,
    exit 2, before any render; nothing written."""
    scene = write_scene(work, BASE)
    extra = [flag, path] + (["--method", "montecarlo", "--passes", "2"] if flag == "--checkpoint" else [])
    err = run_inprocess(render_argv(work, scene) + extra, capsys)
    check_one_line(err, f"{flag} {path}", "not writable")
    check_nothing_written(work)
