"""The repository is self-contained: no file points at design notes outside it, and every page a doc names exists."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# Spelled in pieces so this file does not match itself.
OUTSIDE = ("../" + "shared", "DESIGN" + ".md", "/work/" + "shared")


def _repo_files() -> list[Path]:
    """Tracked files plus untracked ones git does not ignore (what a commit of this tree would hold)."""
    out = subprocess.run(
        ["git", "-C", str(ROOT), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return [ROOT / f for f in out.split("\0") if f and (ROOT / f).is_file()]


def test_no_file_references_outside_design_notes():
    hits = []
    for path in _repo_files():
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue  # binary (PNG, parquet)
        for n, line in enumerate(text.splitlines(), 1):
            if any(s in line for s in OUTSIDE):
                hits.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()[:120]}")
    assert not hits, "files point outside the repository (put the facts in docs/design.md):\n" + "\n".join(hits)


def test_every_named_doc_page_exists():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    missing = []
    for page in pages:
        for name in re.findall(r"`([\w./-]+\.md)`", page.read_text()):
            if not ((ROOT / name).exists() or (page.parent / name).exists()):
                missing.append(f"{page.relative_to(ROOT)} names {name}")
    assert not missing, "\n".join(missing)
    assert (ROOT / "docs" / "design.md").exists()
