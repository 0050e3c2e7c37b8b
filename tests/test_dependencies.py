"""Dependencies are declared, not inherited: every third-party module the packages import comes from a
distribution pyproject.toml names (core or an extra), and the Makefile installs nothing behind pip's back."""

from __future__ import annotations

import re
import sys
import tomllib
from importlib.metadata import packages_distributions
from pathlib import Path

from tests.helpers import absolute_imports

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("kernel", "curbside", "sim", "catalogs", "pipelines", "retrieval")
# Imported only where another declared package has already loaded it (kernel.reproducible quiets its progress bars).
ALLOWED = {"huggingface_hub"}


def _normal(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def third_party_imports() -> dict[str, set[str]]:
    """Top-level module -> the files importing it, over the project's packages (stdlib and own packages left out)."""
    found: dict[str, set[str]] = {}
    for top in PACKAGES:
        for f in (ROOT / top).rglob("*.py"):
            for m in absolute_imports(f.read_text(encoding="utf-8")):
                t = m.split(".")[0]
                if t not in PACKAGES and t not in sys.stdlib_module_names:
                    found.setdefault(t, set()).add(str(f.relative_to(ROOT)))
    return found


def declared() -> set[str]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = project["dependencies"] + [r for extra in project["optional-dependencies"].values() for r in extra]
    return {_normal(re.split(r"[<>=!~\[; ]", r)[0]) for r in reqs}


def undeclared(imports: dict[str, set[str]]) -> dict[str, list[str]]:
    """The modules of `imports` (module -> importing files) that no declared distribution provides."""
    dists = packages_distributions()
    names = declared()
    return {
        m: sorted(files)[:3]
        for m, files in imports.items()
        if m not in ALLOWED and not {_normal(d) for d in dists.get(m, [])} & names
    }


def test_every_third_party_import_is_declared() -> None:
    assert undeclared(third_party_imports()) == {}


def test_the_check_sees_an_undeclared_import() -> None:
    # scipy is a core dependency; d3rlpy (not installed, not declared) is flagged.
    flagged = undeclared({"scipy": {"a.py"}, "d3rlpy": {"b.py"}})
    assert flagged == {"d3rlpy": ["b.py"]}


def test_the_makefile_installs_nothing_without_its_dependencies() -> None:
    assert "--no-deps" not in (ROOT / "Makefile").read_text()
