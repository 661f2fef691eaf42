"""The ```sh command blocks of README.md and docs/ run as written, in a clean temporary folder that
holds only the clone's render.py and scenes/ (as a fresh clone's folder does, minus everything else),
with `python` the interpreter running the tests (the activated .venv of README's "Using it").

Each block's commands run in order in one folder (a later command may read an earlier one's files,
as README's `diff test.exr ref.exr` does), every one expected to exit 0. By default the renders are
shrunk (`SHRINK`: 16x12 pixels, 1 spp; a one-pixel --crop keeps the camera's size, where its pixel
lies); commands that run long as written (the paper's meshes, a 600 s Monte Carlo run, the gallery,
local Dask workers) are left to the `slow` run, which runs every block as written. Lines that
install, run the test suite or name a placeholder host are not commands to run here (`NOT_RUN`); a
line of any other kind fails the test until it is classified, so a new documented command is run.
"""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
SHRINK = {"render": ["--width", "16", "--height", "12", "--spp", "1"],
          "compare": ["--width", "16", "--height", "8", "--spp", "1"],
          "sweep": ["--width", "16", "--height", "8", "--spp", "1"]}
# what a line that is not a render.py command is, and why it is not run here
NOT_RUN = [(re.compile(r"^python3 -m venv |^(\.venv/bin/)?pip install "), "installs (the fresh clone's setup)"),
           (re.compile(r"^\. \.venv/bin/activate$"), "activates the virtual environment (the test's `python` is it)"),
           (re.compile(r"(^|\s)(\.venv/bin/)?python -m pytest\b"), "runs the test suite"),
           (re.compile(r"^(\.venv/bin/)?lint-imports\b"), "the import contracts (.ci/run runs them)"),
           (re.compile(r"\bHOST\b"), "names a placeholder host")]
MESH_SCENES = ("sibenik", "bridge", "conference")  # their meshes come through RAYTRACE_ASSETS


def blocks() -> list[tuple[str, list[str]]]:
    """(page:block number, its commands) for every ```sh block of the pages: continued lines joined,
    comments dropped."""
    out = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for n, body in enumerate(re.findall(r"^```sh\n(.*?)^```", text, re.M | re.S), 1):
            commands = [_uncomment(line) for line in body.replace("\\\n", " ").splitlines()]
            out.append((f"{page.relative_to(ROOT)}:{n}", [c for c in commands if c]))
    return out


def _uncomment(line: str) -> str:
    """`line` without its comment (from a # that opens a word outside quotes, as bash reads it)."""
    quote = None
    for i, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1].isspace()):
            return line[:i].strip()
    return line.strip()


def kind(command: str) -> tuple[str, list[str] | None]:
    """("run", the flags that shrink it) for a render.py command to run by default, ("slow", None) for
    one left to the slow run, ("skip", why) for a line that is not run, ("unknown", None) otherwise."""
    for rx, why in NOT_RUN:
        if rx.search(command):
            return "skip", [why]
    words = shlex.split(command)
    if "render.py" not in words:
        return "unknown", None
    args = words[words.index("render.py") + 1:]
    sub = args[0] if args and not args[0].startswith("-") and args[0] in SUBCOMMANDS else "render"
    if sub == "assets" and "--list" not in args:
        return "skip", ["downloads the paper's meshes (tests/test_assets.py serves fixture archives locally)"]
    if (sub in ("gallery", "table1") or any(w in MESH_SCENES for w in args) or "--time-budget" in args
            or "--scheduler" in args):
        return "slow", None
    if sub == "render" and "--crop" in args:
        return "run", []
    return "run", SHRINK.get(sub, [])


SUBCOMMANDS = ("render", "describe", "methods", "diff", "compare", "sweep", "table1", "seed002", "export", "gallery",
               "assets")


@pytest.fixture
def clone(tmp_path):
    """A clean folder with the clone's render.py and scenes/ and a `python` on PATH that is this
    interpreter (with this checkout's raytrace on PYTHONPATH)."""
    os.symlink(ROOT / "render.py", tmp_path / "render.py")
    os.symlink(ROOT / "scenes", tmp_path / "scenes")
    bin_dir = tmp_path / ".venv" / "bin"
    bin_dir.mkdir(parents=True)
    python = bin_dir / "python"  # a script, not a link: a link to a venv's python loses the venv
    python.write_text(f'#!/bin/sh\nexec {shlex.quote(sys.executable)} "$@"\n')
    python.chmod(0o755)
    env = {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}", "PYTHONPATH": str(ROOT)}
    return tmp_path, env


def _run(folder: Path, env: dict, command: str, extra: list[str]):
    line = command + "".join(f" {shlex.quote(a)}" for a in extra)
    done = subprocess.run(["bash", "-c", line], cwd=folder, env=env, capture_output=True, text=True, timeout=3600)
    assert done.returncode == 0, f"`{line}` exited {done.returncode}:\n{done.stderr[-2000:]}"
    return done


BLOCKS = blocks()
RUN = [b for b in BLOCKS if any(kind(c)[0] == "run" for c in b[1])]  # blocks with a command run by default
WRITTEN = [b for b in BLOCKS if any(kind(c)[0] in ("run", "slow") for c in b[1])]  # ... or by the slow run


def test_every_line_is_classified():
    unknown = [f"{where}: {c}" for where, commands in BLOCKS for c in commands if kind(c)[0] == "unknown"]
    assert unknown == [], "documented commands this test neither runs nor explains:\n" + "\n".join(unknown)


def test_the_extraction_finds_readmes_commands():
    readme = [c for where, commands in BLOCKS if where.startswith("README.md") for c in commands]
    assert "python render.py diff test.exr ref.exr --map err.png" in readme
    assert "python render.py render box_room --set medium.sigma_s=0.2 --set 'medium.phase={type=\"hg\",g=0.5}'" \
        in readme
    assert kind("python render.py render sibenik --method montecarlo --time-budget 600")[0] == "slow"
    assert kind("python render.py compare box_room --methods analytic --out c/") == ("run", SHRINK["compare"])


@pytest.mark.parametrize(("where", "commands"), RUN, ids=[where for where, _ in RUN])
def test_documented_commands_run_at_tiny_sizes(clone, where, commands):
    folder, env = clone
    for c in commands:
        what, extra = kind(c)
        if what == "run":
            _run(folder, env, c, extra)


@pytest.mark.slow
@pytest.mark.parametrize(("where", "commands"), WRITTEN, ids=[where for where, _ in WRITTEN])
def test_documented_commands_run_as_written(clone, where, commands):
    folder, env = clone
    if any(w in c for c in commands for w in MESH_SCENES) and not os.environ.get("RAYTRACE_ASSETS"):
        pytest.skip("the paper's meshes: set RAYTRACE_ASSETS")
    (folder / "docs").mkdir()  # the gallery's --out docs/gallery, as in the clone
    for c in commands:
        if kind(c)[0] in ("run", "slow"):
            _run(folder, env, c, [])
