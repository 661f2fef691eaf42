"""docs/README.md, the documentation's index, links every page of docs/ (Markdown pages and the
notebook) with one line each, and README.md links the index."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
INDEX = ROOT / "docs" / "README.md"


def test_the_index_lists_every_page_once_and_readme_links_it():
    pages = {p.relative_to(INDEX.parent).as_posix() for p in (ROOT / "docs").rglob("*")
             if p.suffix in (".md", ".ipynb") and p != INDEX}
    items = re.findall(r"^- \[[^\]]+\]\(([^)#]+)\) — \S", INDEX.read_text(encoding="utf-8"), re.M)
    assert sorted(items) == sorted(pages), f"missing: {sorted(pages - set(items))}, extra: {sorted(set(items) - pages)}"
    assert len(items) == len(set(items))
    assert "](docs/README.md)" in (ROOT / "README.md").read_text(encoding="utf-8")
