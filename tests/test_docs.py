"""The documentation against the code: docs/scene_format.md lists exactly the keys the parser
accepts, docs/cli.md every command-line flag, README's relative links resolve and it stays short.

The parser is asked, not read: each table's allowed keys come from its own error message for an
unknown key ("allowed keys: ..."), each kind's choices from its message for an unknown value
("choose one of: ..."), so the test follows the parser wherever its code lives.
"""
from __future__ import annotations

import contextlib
import io
import re
import tomllib
from pathlib import Path

import pytest

import raytrace
from raytrace.cli import main as cli_main

ROOT = Path(__file__).resolve().parents[1]
SCENE_FORMAT = ROOT / "docs" / "scene_format.md"
CLI_DOC = ROOT / "docs" / "cli.md"
README = ROOT / "README.md"
BOGUS = "qqqqqqqqqq"  # close to no key, so the parser lists all of them instead of a "did you mean"
CAMERA = {"position": [0.0, 0.0, 4.0], "look_at": [0.0, 0.0, 0.0]}
PLANET = {"type": "atmosphere", "center": [0.0, -1000.0, 0.0], "radius": 990.0, "top_radius": 1100.0}


def _refusal(scene: dict) -> str:
    with pytest.raises(raytrace.UserError) as exc:
        raytrace.load(scene)
    return str(exc.value)


def _listed(message: str, marker: str) -> set[str]:
    m = re.search(re.escape(marker) + r"\s*(.+)$", message)
    assert m, f"the parser's message no longer lists its choices after {marker!r}: {message}"
    return {v.strip() for v in m.group(1).split(",")}


def allowed(scene: dict) -> set[str]:
    """The keys the parser allows where `scene` puts the bogus key."""
    return _listed(_refusal(scene), "allowed keys:")


def choices(scene: dict) -> set[str]:
    """The values the parser allows where `scene` puts the bogus value."""
    return _listed(_refusal(scene), "choose one of:")


def _scene(**tables) -> dict:
    return {"camera": dict(CAMERA), **tables}


def _kinds():
    return {
        "primitive": choices(_scene(shape=[{"primitive": BOGUS}])),
        "light": choices(_scene(light=[{"type": BOGUS}])),
        "medium": choices(_scene(medium={"type": BOGUS})),
    }


def parser_tables() -> dict[str, set[str]]:
    """Context label (as in the first header cell of the reference's tables) → accepted keys."""
    kinds = _kinds()
    out = {
        "(top level)": allowed({**_scene(), BOGUS: 1}),
        "[camera]": allowed({"camera": {**CAMERA, BOGUS: 1}}),
        "[[shape]]": allowed(_scene(shape=[{"mesh": "a.obj", BOGUS: 1}])),
        "transform = { ... }": allowed(_scene(shape=[{"mesh": "a.obj", "transform": {BOGUS: 1}}])),
        "interior = { ... }": allowed(_scene(shape=[{"primitive": "sphere", "center": [0, 0, 0], "radius": 1.0,
                                                     "interior": {BOGUS: 1}}])),
        "[medium.particles]": allowed(_scene(medium={"sigma_s": 0.1, "particles": {BOGUS: 1}})),
        "[[medium.layer]]": allowed(_scene(medium={**PLANET, "layer": [{"scale_height": 10.0, BOGUS: 1}]})),
        "phase = { ... }": allowed(_scene(medium={"phase": {"type": "hg", "g": 0.5, BOGUS: 1}})),
        "[background]": allowed(_scene(background={BOGUS: 1})),
        "[render]": allowed(_scene(render={BOGUS: 1})),
    }
    common = out["[[shape]]"]
    for kind in kinds["primitive"]:
        out[f'[[shape]] primitive = "{kind}"'] = allowed(_scene(shape=[{"primitive": kind, BOGUS: 1}])) - common
    for kind in kinds["light"]:
        out[f'[[light]] type = "{kind}"'] = allowed(_scene(light=[{"type": kind, BOGUS: 1}]))
    for kind in kinds["medium"]:
        out[f'[medium] type = "{kind}"'] = allowed(_scene(medium={"type": kind, BOGUS: 1}))
    return out


def parser_values() -> dict[tuple[str, str], set[str]]:
    """(context label, key) → the string values the parser allows there."""
    fog = {"type": "height_fog", "scale_height": 1.0}
    return {
        ("[camera]", "type"): choices({"camera": {**CAMERA, "type": BOGUS}}),
        ("[[shape]]", "primitive"): _kinds()["primitive"],
        ('[[light]] type = "point"', "type"): _kinds()["light"],
        ('[medium] type = "homogeneous"', "type"): _kinds()["medium"],
        ('[medium] type = "height_fog"', "profile"): choices(_scene(medium={**fog, "profile": BOGUS})),
        ("phase = { ... }", "type"): choices(_scene(medium={"phase": {"type": BOGUS}})),
        ("[render]", "method"): choices(_scene(render={"method": BOGUS})),
    }


def doc_tables(path: Path) -> dict[str, dict[str, str]]:
    """Tables whose first header cell is "key in `CONTEXT`" (or "top-level key"): context → {key: row}."""
    tables: dict[str, dict[str, str]] = {}
    current = None
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("|"):
            current = None
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        head = re.fullmatch(r"key in `(.+)`", cells[0])
        if current is None and (head or cells[0] == "top-level key"):
            current = head.group(1) if head else "(top level)"
            assert current not in tables, f"{path.name}: two tables for {current}"
            tables[current] = {}
        elif current is not None and not set(cells[0]) <= set("-: "):
            keys = re.findall(r"`([A-Za-z_][A-Za-z0-9_]*)`", cells[0])
            assert keys, f"{path.name}: a row of {current} names no key in backticks: {line}"
            for k in keys:
                tables[current][k] = line
    return tables


def test_scene_reference_lists_exactly_the_parsers_keys():
    documented = doc_tables(SCENE_FORMAT)
    accepted = parser_tables()
    problems = []
    for context in sorted(set(accepted) | set(documented)):
        if context not in documented:
            problems.append(f"no table 'key in `{context}`' for keys {sorted(accepted[context])}")
        elif context not in accepted:
            problems.append(f"table for {context}, which the parser does not have")
        else:
            if missing := accepted[context] - set(documented[context]):
                problems.append(f"{context}: accepted but not documented: {sorted(missing)}")
            if refused := set(documented[context]) - accepted[context]:
                problems.append(f"{context}: documented but refused: {sorted(refused)}")
    assert not problems, "docs/scene_format.md is out of date:\n" + "\n".join(problems)


def test_scene_reference_lists_every_choice():
    documented = doc_tables(SCENE_FORMAT)
    problems = []
    for (context, key), values in parser_values().items():
        row = documented.get(context, {}).get(key, "")
        problems += [f"{context} {key}: \"{v}\" not in its row" for v in sorted(values) if f'"{v}"' not in row]
    assert not problems, "docs/scene_format.md is out of date:\n" + "\n".join(problems)


def test_scene_reference_examples_parse():
    blocks = re.findall(r"```toml\n(.*?)```", SCENE_FORMAT.read_text(encoding="utf-8"), re.S)
    assert len(blocks) >= 5
    for block in blocks:
        scene = tomllib.loads(block)
        scene.setdefault("camera", dict(CAMERA))
        raytrace.load(scene)  # a UserError here names the key the example gets wrong


def _help(*args) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        cli_main([*args, "--help"])
    return out.getvalue()


def cli_flags() -> dict[str, set[str]]:
    """Subcommand → its flags, from the command line's own --help."""
    commands = re.search(r"\{([a-z0-9_,]+)\}", _help()).group(1).split(",")
    return {c: set(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", _help(c))) - {"--help"} for c in commands}


def test_cli_reference_lists_every_command_and_flag():
    text = CLI_DOC.read_text(encoding="utf-8")
    sections = dict(re.findall(r"^## `([a-z0-9_]+)`.*\n((?:(?!^## ).*\n?)*)", text, re.M))
    problems = []
    for command, flags in cli_flags().items():
        if command not in sections:
            problems.append(f"no section '## `{command}`'")
            continue
        problems += [f"{command}: {f} not documented" for f in sorted(flags)
                     if not re.search(rf"`{re.escape(f)}(?![\w-])", sections[command])]
        documented = set(re.findall(r"^\| `(--[a-z][a-z0-9-]*)", sections[command], re.M))
        problems += [f"{command}: documents {f}, which it does not take" for f in sorted(documented - flags)]
    assert not problems, "docs/cli.md is out of date:\n" + "\n".join(problems)


def _slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading: lower case, punctuation dropped, spaces as hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _broken_links(page: Path) -> list[str]:
    """Relative links of `page` whose file, or whose #anchor in a Markdown file, does not exist."""
    broken = []
    text = page.read_text(encoding="utf-8")
    for target, anchor in re.findall(r"\]\(([^)#\s]*)(?:#([^)\s]*))?\)", text):
        if re.match(r"[a-z]+:", target):
            continue
        path = (page.parent / target) if target else page
        if not path.exists():
            broken.append(f"{page.name}: {target}")
        elif anchor and path.suffix == ".md":
            headings = re.findall(r"^#+ (.+)$", path.read_text(encoding="utf-8"), re.M)
            if anchor not in {_slug(h) for h in headings}:
                broken.append(f"{page.name}: {target}#{anchor}")
    return broken


def test_readme_links_resolve_and_it_stays_short():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 300
    assert re.search(r"\]\(docs/", text), "README links to no docs"
    assert _broken_links(README) == []


def test_docs_links_resolve():
    broken = [b for page in sorted((ROOT / "docs").rglob("*.md")) for b in _broken_links(page)]
    assert broken == []


def test_readme_names_every_bundled_scene_and_its_two_commands():
    text = README.read_text(encoding="utf-8")
    scenes = sorted(p.stem for p in (ROOT / "scenes").glob("*.toml"))
    assert [s for s in scenes if f"`{s}`" not in text] == []
    first = text.split("```")[1]
    assert ".venv/bin/pip install -q -e . && .venv/bin/python render.py" in first
    assert '.venv/bin/pip install -q -e ".[test,distributed,plots]" && .venv/bin/python -m pytest' in first


# Pages are for users: no commit ids, no numbers of this project's issues, the papers by title.
HEX_ID = re.compile(r"(?<![\w#])[0-9a-f]{7,40}(?!\w)")                # a git hash, short or full
ISSUE_NO = re.compile(r"\bissues?\s+#?\d+|(?<![\w/-])#\d+\b", re.I)      # "issue 15", "#22"; not pbrt-v4#433
SEED_NO = re.compile(r"(?<![\w/.-])seed[ _-]?00\d(?!\w|/|\.\w)", re.I)  # "seed 002"; not seed002.py, seed002/
ANECDOTE = re.compile(r"load average|\b1-minute load|\bload \d|\b(?:loaded|busy|quiet|shared)(?: [\w-]+){0,2} machine"
                      r"|\bmachine (?:shared|under load|loaded)|\bcores? (?:loaded|shared)|\bother (?:jobs|engineers)"
                      r"|shared with other", re.I)  # how busy the machine was: figures name the machine once, neutrally


def _commit_ids(line: str) -> list[str]:
    """Hex words of 7-40 digits with a digit and a letter, outside URLs; not colours (#...) nor 1e100."""
    words = HEX_ID.findall(re.sub(r"https?://\S*", " ", line))
    return [w for w in words if re.search(r"\d", w) and re.search(r"[a-f]", w) and not re.fullmatch(r"\d+e\d+", w)]


def _prose(line: str) -> str:
    """A line without its URLs, inline code and link targets: what reads as text."""
    line = re.sub(r"https?://[^\s)>]*", " ", line)
    line = re.sub(r"`[^`]*`", " ", line)
    return re.sub(r"\]\([^)]*\)", "]", line)


def work_notes(page: Path) -> list[str]:
    """line: what, for each commit id, issue number, "seed 00N" or machine anecdote on `page`; issue
    numbers, paper numbers and anecdotes count in prose only (not in code blocks, code spans, links)."""
    found = []
    fenced = False
    for n, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
        if line.lstrip().startswith("```"):
            fenced = not fenced
        found += [f"{n}: commit id {w}" for w in _commit_ids(line)]
        if not fenced:
            found += [f"{n}: {m.group(0)!r}" for rx in (ISSUE_NO, SEED_NO, ANECDOTE) for m in rx.finditer(_prose(line))]
    return found


def test_work_notes_are_found(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("Fixed at 3e4f5f6 (Issue 15, #22), on main (abc1234), as seed 002 says.\n"
                    "The Seed-004 page; a loaded machine, load average 3, 2 cores shared with other jobs.\n"
                    "```sh\ngit checkout 0123abcdef456789 # issue 3 in code is not prose\n```\n"
                    "pbrt-v4#433, `python render.py seed002` and `seed 002`, [report](seed002/report.md),\n"
                    "raytrace/experiments/seed002.py, tests/test_seed002.py, 6360000, 2.5e-12, 1e10000, defaced,\n"
                    "colour #a1b2c3d4, <https://github.com/o/r/commit/3e4f5f6a>, ../papers/002_debc87b35cc1caf8.txt.\n",
                    encoding="utf-8")
    assert work_notes(page) == [
        "1: commit id 3e4f5f6", "1: commit id abc1234", "1: 'Issue 15'", "1: '#22'", "1: 'seed 002'",
        "2: 'Seed-004'", "2: 'loaded machine'", "2: 'load average'", "2: 'cores shared'", "2: 'other jobs'",
        "4: commit id 0123abcdef456789"]


def test_pages_cite_no_commits_issues_or_paper_numbers():
    found = [f"{page.relative_to(ROOT)}:{w}" for page in [README, *sorted((ROOT / "docs").rglob("*.md"))]
             for w in work_notes(page)]
    assert found == [], "pages for users carry work notes (cite papers by title):\n" + "\n".join(found)
