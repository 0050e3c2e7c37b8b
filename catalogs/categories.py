"""The one category table (`categories.csv` beside this module): object class, zones, typical size and size priors.

Pipelines check the categories they extract against it, retrieval normalises and files assets by it, and the
scene generator draws and places objects by it (docs/categories.md). Only the standard library reads it, so
every room can import it; no other file may define categories (tests/catalogs/test_categories.py).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from functools import cache
from importlib import resources

from catalogs.schema import OBJECT_CLASSES, ZONES
from kernel.config import ConfigError

AXES = ("depth", "width", "height")
COLUMNS = ("category", "object_class", "zones", *AXES, *(f"{a}_{e}" for a in AXES for e in ("min", "max")), "sources")


@dataclass(frozen=True)
class Category:
    """One row: where a category belongs, the box a scene uses without an asset, and its plausible extents (m)."""

    name: str
    object_class: str
    zones: tuple[str, ...]  # designated zones, in order of preference
    size: tuple[float, float, float]  # typical (depth, width, height)
    depth: tuple[float, float]
    width: tuple[float, float]
    height: tuple[float, float]
    sources: str

    def range(self, axis: str) -> tuple[float, float]:
        """The (min, max) prior of `axis` ('depth', 'width' or 'height')."""
        if axis not in AXES:
            raise ValueError(f"unknown axis {axis!r}; use one of {', '.join(AXES)}")
        return getattr(self, axis)

    @property
    def words(self) -> str:
        """Human words for the name ('trash_bin' -> 'trash bin')."""
        return self.name.replace("_", " ")


def parse_table(text: str, where: str = "catalogs/categories.csv") -> dict[str, Category]:
    """Parse and validate a category table's text into {name: Category} in row order; errors name the line."""
    reader = csv.DictReader(line for line in text.splitlines() if not line.startswith("#"))
    missing = [c for c in COLUMNS if c not in (reader.fieldnames or [])]
    if missing:
        raise ValueError(f"{where}: missing columns {missing}; expected {list(COLUMNS)}")
    table: dict[str, Category] = {}
    for i, row in enumerate(reader, start=1):
        at = f"{where} row {i} ({row['category']!r})"
        if row["object_class"] not in OBJECT_CLASSES:
            raise ValueError(f"{at}: object_class {row['object_class']!r} is not one of {OBJECT_CLASSES}")
        zones = tuple(row["zones"].split())
        if not zones or set(zones) - set(ZONES):
            raise ValueError(f"{at}: zones {row['zones']!r} invalid; use space-separated names from {ZONES}")
        ranges = {}
        for a in AXES:
            lo, hi, typical = float(row[f"{a}_min"]), float(row[f"{a}_max"]), float(row[a])
            if not 0 < lo <= typical <= hi:
                raise ValueError(f"{at}: {a} needs 0 < {a}_min <= {a} <= {a}_max, got {lo}, {typical}, {hi}")
            ranges[a] = (lo, hi)
        if row["category"] in table:
            raise ValueError(f"{at}: duplicate category; each category has one row")
        if not row["sources"].strip():
            raise ValueError(f"{at}: the sources column is empty; name where the sizes come from")
        table[row["category"]] = Category(
            row["category"],
            row["object_class"],
            zones,
            (float(row[AXES[0]]), float(row[AXES[1]]), float(row[AXES[2]])),
            sources=row["sources"],
            **ranges,
        )
    return table


def _load() -> dict[str, Category]:
    text = resources.files("catalogs").joinpath("categories.csv").read_text(encoding="utf-8")
    return parse_table(text)


CATEGORIES: dict[str, Category] = _load()
NAMES: tuple[str, ...] = tuple(CATEGORIES)


def category(name: str, *, where: str = "category") -> Category:
    """The row of `name`; raises naming `where` it came from and the valid names."""
    try:
        return CATEGORIES[name]
    except (KeyError, TypeError):  # TypeError: an unhashable value (a list where a name belongs)
        raise ConfigError(
            f"{where}: {name!r} is not in the curbside vocabulary (catalogs/categories.csv); "
            f"use one of: {', '.join(NAMES)}"
        ) from None


def check_category(name: str, *, where: str) -> str:
    """Return `name` if it is a category, else raise naming `where` it came from."""
    return category(name, where=where).name


@cache
def of_class(object_class: str) -> tuple[str, ...]:
    """The categories of `object_class`, in table order."""
    if object_class not in OBJECT_CLASSES:
        raise ValueError(f"unknown object class {object_class!r}; use one of {OBJECT_CLASSES}")
    return tuple(c.name for c in CATEGORIES.values() if c.object_class == object_class)


@cache
def zones_of_class(object_class: str) -> tuple[str, ...]:
    """Every zone some category of `object_class` may stand in, in catalogs.schema.ZONES order."""
    used = {z for c in of_class(object_class) for z in CATEGORIES[c].zones}
    return tuple(z for z in ZONES if z in used)
