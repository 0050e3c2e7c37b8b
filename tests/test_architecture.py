"""The one-way data flow of docs/architecture.md, checked on every import statement; catalog SQL only in catalogs/."""

from __future__ import annotations

import ast
import re
import subprocess
from pathlib import Path

from tests.helpers import absolute_imports

ROOT = Path(__file__).resolve().parents[1]
KERNEL = {"kernel"}
# What each room may import from the other rooms (the kernel is shared by all; the CLI and training sit on top).
ALLOWED = {
    "kernel": set(),
    "catalogs": KERNEL,
    "retrieval": KERNEL | {"catalogs"},
    "pipelines": KERNEL | {"catalogs", "retrieval"},
    "sim": KERNEL | {"catalogs"},
}
ROOMS = ("kernel", "pipelines", "retrieval", "catalogs", "sim", "curbside")


def _room(path: Path) -> str | None:
    rel = path.relative_to(ROOT).with_suffix("")
    return None if rel.parts[0] == "curbside" else rel.parts[0]  # curbside (cli, train) may import anything


def _target(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] not in ROOMS:
        return None
    return parts[0]


def bad_imports(room: str, source: str) -> list[str]:
    """The modules `source` (a file of `room`) imports against the data flow."""
    bad = []
    for m in absolute_imports(source):
        t = _target(m)
        own = "kernel" if t in KERNEL else t
        if t is not None and own != room and t not in ALLOWED[room]:
            bad.append(m)
    return bad


def test_imports_follow_the_data_flow() -> None:
    bad = [
        f"{f.relative_to(ROOT)}: {m}"
        for top in ROOMS
        for f in sorted((ROOT / top).rglob("*.py"))
        if (room := _room(f)) is not None
        for m in bad_imports(room, f.read_text(encoding="utf-8"))
    ]
    assert bad == []


def test_the_check_sees_violations() -> None:
    assert bad_imports("sim", "import retrieval.ingest\nfrom pipelines import osm\nimport catalogs.reader\n") == [
        "retrieval.ingest",
        "pipelines",
    ]
    assert bad_imports("catalogs", "def f():\n    from sim.scene import generate_scene\n") == ["sim.scene"]
    assert bad_imports("kernel", "import curbside.cli.main\n") == ["curbside.cli.main"]  # the CLI sits on top
    assert bad_imports("kernel", "from catalogs import reader\n") == ["catalogs"]


def _catalog_tables() -> tuple[str, ...]:
    """The table names the catalog schema creates."""
    from catalogs.schema import ddl

    return tuple(re.search(r"CREATE TABLE IF NOT EXISTS (\w+)", stmt).group(1) for stmt in ddl())


def catalog_sql(source: str, tables: tuple[str, ...]) -> list[int]:
    """Lines of `source` whose string literals hold SQL on a catalog table (or on a table named at run time)."""
    named = re.compile(rf"\b(?:FROM|JOIN|INTO|UPDATE|TABLE)\s+\"?(?:{'|'.join(tables)})\b", re.IGNORECASE)
    dynamic = re.compile(r"\b(?:FROM|JOIN|INTO|UPDATE|TABLE)\s+\"?\{\}")  # upper case: prose says "from {path}"
    tree = ast.parse(source)
    # Docstrings describe tables in prose ("rows from assets"); only strings the code uses can be SQL.
    docs = {
        id(body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
        and (body := node.body)
        and isinstance(body[0], ast.Expr)
    }
    lines = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs:
            text = node.value
        elif isinstance(node, ast.JoinedStr):
            text = "".join(v.value if isinstance(v, ast.Constant) else "{}" for v in node.values)
        else:
            continue
        if named.search(text) or dynamic.search(text):
            lines.add(node.lineno)
    return sorted(lines)


def test_catalog_sql_lives_in_catalogs() -> None:
    # The catalog's tables are a contract owned by catalogs/ (writer, reader, query, inspect): code elsewhere
    # calls their functions, so a schema change touches one package (docs/architecture.md).
    tables = _catalog_tables()
    files = subprocess.run(
        ["git", "-C", str(ROOT), "ls-files", "--cached", "--others", "--exclude-standard", "*.py"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    bad = {
        f: lines
        for f in sorted(set(files))
        if f.split("/")[0] not in ("catalogs", "tests")
        and (ROOT / f).is_file()
        and (lines := catalog_sql((ROOT / f).read_text(encoding="utf-8"), tables))
    }
    assert bad == {}


def test_the_sql_check_sees_sql() -> None:
    tables = _catalog_tables()
    assert {"assets", "views", "matches", "embeddings", "rejections", "descriptions", "meta"} <= set(tables)
    src = (
        '"""Reads rows from assets."""\n'
        'a = con.execute("SELECT asset_id FROM assets")\n'
        'b = con.execute(f"DELETE FROM {table} WHERE asset_id = ?")\n'
        'c = "select m.score from matches m " "join descriptions d using (description_id)"\n'
        'd = con.execute("SELECT * FROM read_parquet(?)")\n'
        'e = f"no catalog from {path}"\n'
    )
    assert catalog_sql(src, tables) == [2, 3, 4]
