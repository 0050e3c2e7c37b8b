"""The one category table: its loader's checks, and that no other file defines categories."""

from __future__ import annotations

import ast
import csv
import subprocess
from pathlib import Path

import pytest

from catalogs.categories import CATEGORIES, NAMES, category, of_class, parse_table, zones_of_class
from catalogs.schema import OBJECT_CLASSES, ZONES

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "catalogs" / "categories.csv"


def _tracked(pattern: str) -> list[Path]:
    out = subprocess.run(
        ["git", "-C", str(ROOT), "ls-files", "--cached", "--others", "--exclude-standard", pattern],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    return [ROOT / f for f in sorted(set(out)) if (ROOT / f).is_file()]


def test_the_table_holds_every_category_once_with_valid_rows() -> None:
    assert len(NAMES) == 33 and len(set(NAMES)) == 33
    assert {c.object_class for c in CATEGORIES.values()} == set(OBJECT_CLASSES)
    for c in CATEGORIES.values():
        assert c.zones and set(c.zones) <= set(ZONES)
        for axis, typical in zip(("depth", "width", "height"), c.size, strict=True):
            lo, hi = c.range(axis)
            assert 0 < lo <= typical <= hi
    assert of_class("clutter")[0] == "traffic_cone" and "building_facade" in of_class("non_standard")
    assert zones_of_class("clutter") == ("near_road_buffer", "furnishing", "clear", "frontage_buffer", "frontage")
    assert CATEGORIES["building_facade"].zones == ("building",)


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("furnishing near_road_buffer", "furnishing kerb", "zones 'furnishing kerb' invalid"),
        (",standard,", ",infrastructure,", "object_class 'infrastructure'"),
        ("0.3,0.3,6.0,", "0.3,0.3,16.0,", "height needs 0 < height_min <= height <= height_max"),
        ("\nbench,", "\nstreet_lamp,", "duplicate category"),
    ],
)
def test_a_bad_row_is_refused_naming_its_row_and_the_fix(old: str, new: str, message: str) -> None:
    text = TABLE.read_text(encoding="utf-8")
    assert old in text
    with pytest.raises(ValueError, match=message):
        parse_table(text.replace(old, new, 1))


def test_unknown_names_are_refused_listing_the_valid_ones() -> None:
    with pytest.raises(ValueError, match="hoverboard.*not in the curbside vocabulary.*street_lamp"):
        category("hoverboard", where="my.csv row 3")


def _names_in(node: ast.AST) -> set[str]:
    """Category names `node` lists: as elements of a list, tuple or set, or as dict keys (a mapping from another
    vocabulary onto ours, such as Objaverse's LVIS names, holds them as values)."""
    listed = [e for n in ast.walk(node) if isinstance(n, (ast.List, ast.Tuple, ast.Set)) for e in n.elts]
    listed += [k for n in ast.walk(node) if isinstance(n, ast.Dict) for k in n.keys if k is not None]
    return {e.value for e in listed if isinstance(e, ast.Constant) and e.value in CATEGORIES}


def defining_statements(source: str, at_least: int = 12) -> list[int]:
    """Lines of top-level or class-level statements that spell out `at_least` category names (a second table)."""
    tree = ast.parse(source)
    stmts = [s for s in tree.body] + [s for c in tree.body if isinstance(c, ast.ClassDef) for s in c.body]
    return [
        s.lineno for s in stmts if not isinstance(s, (ast.FunctionDef, ast.ClassDef)) and len(_names_in(s)) >= at_least
    ]


def test_the_definition_check_sees_a_second_table() -> None:
    groups = f"GROUPS = {{'standard': {list(of_class('standard'))}, 'clutter': {list(of_class('clutter'))}}}\n"
    lvis = "LVIS = {" + ", ".join(f"'{c}_lvis': '{c}'" for c in NAMES) + "}\n"
    assert defining_statements("HELD_OUT = ['kiosk', 'e_scooter', 'food_cart']\n" + groups + lvis) == [2]


def test_nothing_else_defines_categories() -> None:
    # Code may name a few categories (a held-out split, a test's sample), never spell out the vocabulary again.
    code = {
        str(f.relative_to(ROOT)): lines
        for f in _tracked("*.py")
        if f.parts[len(ROOT.parts)] != "tests" and (lines := defining_statements(f.read_text(encoding="utf-8")))
    }
    assert code == {}
    # A data table that gives categories a class or zones is a second category table.
    tables = []
    for f in _tracked("*.csv"):
        with f.open(encoding="utf-8", newline="") as fh:
            header = next(csv.reader(line for line in fh if not line.startswith("#")), [])
        if f != TABLE and "category" in header and {"object_class", "zones", "group"} & set(header):
            tables.append(str(f.relative_to(ROOT)))
    assert tables == []
