"""The procedural recipes (`recipes.csv`): per category of catalogs/categories.csv, the generator's size ranges (inside
the category's priors), mass, colour variants, description template, synonyms and sources."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

from catalogs.categories import AXES, category

TABLE_PATH = Path(__file__).with_name("recipes.csv")

COLUMNS = (
    "category",
    "depth_min",
    "depth_max",
    "width_min",
    "width_max",
    "height_min",
    "height_max",
    "mass_min",
    "mass_max",
    "variants",
    "description",
    "synonyms",
    "source",
)


@dataclass(frozen=True)
class Variant:
    """A colour/material variant: a colour name, a material name and the body colour (RGBA uint8)."""

    color: str
    material: str
    rgba: tuple[int, int, int, int]


@dataclass(frozen=True)
class CategorySpec:
    """One recipe with its category's class and zones: the generator's size ranges (m), mass range (kg) and texts."""

    name: str
    object_class: str
    zones: tuple[str, ...]
    depth: tuple[float, float]
    width: tuple[float, float]
    height: tuple[float, float]
    mass: tuple[float, float]
    variants: tuple[Variant, ...]
    description: str
    synonyms: tuple[str, ...]
    source: str

    def range(self, axis: str) -> tuple[float, float]:
        """The (min, max) range of `axis` ('depth', 'width' or 'height')."""
        if axis not in ("depth", "width", "height"):
            raise ValueError(f"unknown axis {axis!r}; use one of 'depth', 'width', 'height'")
        return getattr(self, axis)


def hex_to_rgba(text: str) -> tuple[int, int, int, int]:
    """Parse '#rrggbb' into an opaque RGBA tuple."""
    s = text.strip().lstrip("#")
    if len(s) != 6:
        raise ValueError(f"colour {text!r} is not of the form #rrggbb")
    return (int(s[0:2], 16), int(s[2:4], 16), int(s[4:6], 16), 255)


def _floats(row: dict[str, str], key: str, where: str) -> tuple[float, float]:
    lo, hi = float(row[f"{key}_min"]), float(row[f"{key}_max"])
    if not 0 < lo <= hi:
        raise ValueError(f"{where}: {key}_min={lo} / {key}_max={hi} must satisfy 0 < min <= max; fix the table")
    return (lo, hi)


def _parse_row(row: dict[str, str], where: str) -> CategorySpec:
    cat = category(row["category"].strip(), where=where)
    variants = []
    for item in row["variants"].split(";"):
        parts = [p.strip() for p in item.split("|")]
        if len(parts) != 3:
            raise ValueError(f"{where}: variant {item!r} must be 'colour|material|#rrggbb'")
        variants.append(Variant(parts[0], parts[1], hex_to_rgba(parts[2])))
    synonyms = tuple(s.strip() for s in row["synonyms"].split(";") if s.strip())
    if not row["source"].strip():
        raise ValueError(f"{where}: the source column is empty; name where the ranges come from")
    ranges = {a: _floats(row, a, where) for a in AXES}
    for a, (lo, hi) in ranges.items():
        plo, phi = cat.range(a)
        if lo < plo or hi > phi:
            raise ValueError(
                f"{where}: {a} {lo}..{hi} leaves the category's prior {plo}..{phi}; generated assets must "
                "pass curation: narrow the recipe or widen the prior in catalogs/categories.csv"
            )
    return CategorySpec(
        name=cat.name,
        object_class=cat.object_class,
        zones=cat.zones,
        **ranges,
        mass=_floats(row, "mass", where),
        variants=tuple(variants),
        description=row["description"].strip(),
        synonyms=synonyms,
        source=row["source"].strip(),
    )


def load_recipes(path: Path = TABLE_PATH) -> dict[str, CategorySpec]:
    """Read the recipe table into {name: CategorySpec}, validating every row against its category."""
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(io.StringIO("".join(line for line in f if not line.startswith("#"))))
        missing = [c for c in COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: missing columns {missing}; expected {COLUMNS}")
        specs: dict[str, CategorySpec] = {}
        for i, row in enumerate(reader, start=2):
            spec = _parse_row(row, f"{path.name} line {i}")
            if spec.name in specs:
                raise ValueError(f"{path.name} line {i}: duplicate category {spec.name!r}")
            specs[spec.name] = spec
    return specs
