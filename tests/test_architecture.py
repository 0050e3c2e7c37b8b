"""The one-way data flow of docs/architecture.md, checked on every import statement of the packages."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
KERNEL = {"curbside.config", "curbside.quiet", "curbside.reproducible"}
# What each room may import from the other rooms (the kernel is shared by all; the CLI and training sit on top).
ALLOWED = {
    "kernel": set(),
    "catalogs": KERNEL,
    "retrieval": KERNEL | {"catalogs"},
    "pipelines": KERNEL | {"catalogs", "retrieval"},
    "sim": KERNEL | {"catalogs"},
}
ROOMS = ("pipelines", "retrieval", "catalogs", "sim", "curbside")


def _room(path: Path) -> str | None:
    rel = path.relative_to(ROOT).with_suffix("")
    if rel.parts[0] == "curbside":
        return "kernel" if ".".join(rel.parts[:2]) in KERNEL else None  # cli and train may import anything
    return rel.parts[0]


def _target(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] not in ROOMS:
        return None
    return ".".join(parts[:2]) if parts[0] == "curbside" else parts[0]


def bad_imports(room: str, source: str) -> list[str]:
    """The modules `source` (a file of `room`) imports against the data flow."""
    bad = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            mods = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            mods = [node.module]
        else:
            continue
        for m in mods:
            t = _target(m)
            own = "kernel" if t in KERNEL else t
            if t is not None and own != room and t not in ALLOWED[room]:
                bad.append(m)
    return bad


def test_imports_follow_the_data_flow() -> None:
    bad = [f"{f.relative_to(ROOT)}: {m}" for top in ROOMS for f in sorted((ROOT / top).rglob("*.py"))
           if (room := _room(f)) is not None for m in bad_imports(room, f.read_text(encoding="utf-8"))]
    assert bad == []


def test_the_check_sees_violations() -> None:
    assert bad_imports("sim", "import retrieval.ingest\nfrom pipelines import osm\nimport catalogs.reader\n") == [
        "retrieval.ingest", "pipelines"]
    assert bad_imports("catalogs", "def f():\n    from sim.scene import generate_scene\n") == ["sim.scene"]
    assert bad_imports("kernel", "import curbside.cli.main\n") == ["curbside.cli.main"]  # the CLI sits on top
    assert bad_imports("kernel", "from catalogs import reader\n") == ["catalogs"]


def test_sim_files_stay_small() -> None:
    # A file past 300 lines holds more than one responsibility: split it (docs/architecture.md).
    long = {str(f.relative_to(ROOT)): n for f in sorted((ROOT / "sim").rglob("*.py"))
            if (n := len(f.read_text(encoding="utf-8").splitlines())) > 300}
    assert long == {}
