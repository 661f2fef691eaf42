"""Small points of the command line's text: a --set value that opens as TOML but is not well formed
is refused as bad TOML for its key, with the fix; counts take the right number ("1 entry");
`methods` prints whole-number bounds in full; every table of docs/cli.md has as many cells in each
row as in its header."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

import raytrace
from raytrace.cli import main
from raytrace.errors import counted

from .conftest import box_room, to_toml

DOCS = Path(__file__).resolve().parents[1] / "docs"


@pytest.mark.parametrize("override, what, example", [
    ("light.0.position=[1,2", "Unclosed array", "--set 'light[0].position=[1, 2, 3]'"),
    ('medium.phase={type="hg"', "Unclosed inline table", "--set 'medium.phase={type = \"hg\", g = 0.5}'"),
    ('name="abc', "Unterminated string", "--set 'name=\"text\"'"),
])
def test_a_bad_toml_value_is_named_as_such(override, what, example):
    with pytest.raises(raytrace.UserError) as e:
        raytrace.load(box_room(), overrides=[override])
    msg = str(e.value)
    key = override.split("=")[0].replace(".0.", "[0].")
    assert msg.startswith(f"scene dict: --set {key}={override.split('=', 1)[1]}: bad TOML ({what}); write a "
                          "complete TOML "), msg
    assert msg.endswith(f"quoted for the shell, e.g. {example}") and "expected" not in msg, msg


def test_a_bare_word_is_still_a_string():
    assert raytrace.load(box_room(), overrides=["render.method=quadrature"]).render["method"] == "quadrature"


def test_counted():
    assert [counted(n, "entry", "entries") for n in (0, 1, 2)] == ["0 entries", "1 entry", "2 entries"]
    assert counted(1, "row") == "1 row" and counted(3, "row") == "3 rows"


def test_an_index_past_one_entry_says_entry():
    with pytest.raises(raytrace.UserError, match=r"--set light\[3\]\.intensity: light has 1 entry; index it as "
                                                 r"light\[0\]$"):
        raytrace.load(box_room(), overrides=["light[3].intensity=2"])


def test_describe_counts_one_triangle(tmp_path, capsys):
    scene = box_room(shape=[{"primitive": "triangles", "vertices": [[0, 0, -1], [1, 0, -1], [0, 1, -1]],
                             "faces": [[0, 1, 2]]}])
    path = tmp_path / "t.toml"
    path.write_text(to_toml(scene))
    assert main(["describe", str(path)]) == 0
    assert "shapes: 1 (triangles: 1), 1 triangle (zero-area" in capsys.readouterr().out


def test_a_memory_band_of_one_row_says_row():
    from types import SimpleNamespace

    from raytrace.api import PIXEL_BYTES, check_memory

    cam = SimpleNamespace(width=1000, height=1000)
    with pytest.raises(raytrace.UserError, match=r"bands of at most 1 row with --crop"):
        check_memory(cam, None, False, "t", max_memory=1.5 * 1000 * PIXEL_BYTES / 2**30)


def test_methods_prints_whole_numbers_in_full(capsys):
    assert main(["methods"]) == 0
    text = capsys.readouterr().out
    assert "<= 1048576)" in text and not re.search(r"\de\+\d", text), text


def _cells(row: str) -> int:
    return len(re.split(r"(?<!\\)\|", row.strip().strip("|")))


def test_every_table_of_the_cli_reference_is_rectangular():
    table = None
    for n, line in enumerate((DOCS / "cli.md").read_text().splitlines(), 1):
        if not line.startswith("|"):
            table = None
        elif table is None:
            table = _cells(line)  # the header
        else:
            assert _cells(line) == table, f"docs/cli.md:{n}: {_cells(line)} cells, the header has {table}: {line}"
