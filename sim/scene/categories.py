"""Object categories: class, designated zones, fallback box sizes, and category distributions."""

from __future__ import annotations

from bisect import bisect_right
from pathlib import Path
from typing import Any

import numpy as np

from curbside.config import ConfigError

# Each category: (object class, designated zones, fallback size [depth, width, height] in metres).
# Depth is the extent along the object's front (+x), which faces away from the road.
CATEGORIES: dict[str, tuple[str, tuple[str, ...], tuple[float, float, float]]] = {
    "street_lamp": ("standard", ("furnishing",), (0.3, 0.3, 6.0)),
    "utility_pole": ("standard", ("furnishing",), (0.35, 0.35, 9.0)),
    "traffic_sign": ("standard", ("furnishing",), (0.1, 0.6, 2.5)),
    "traffic_light": ("standard", ("furnishing",), (0.4, 0.4, 3.5)),
    "fire_hydrant": ("standard", ("furnishing",), (0.4, 0.4, 0.8)),
    "bollard": ("standard", ("furnishing",), (0.25, 0.25, 1.0)),
    "tree": ("standard", ("furnishing",), (1.2, 1.2, 6.0)),
    "parking_meter": ("standard", ("furnishing",), (0.3, 0.3, 1.4)),
    "bench": ("non_standard", ("furnishing", "frontage"), (0.6, 1.8, 0.85)),
    "trash_bin": ("non_standard", ("furnishing", "frontage"), (0.6, 0.6, 1.0)),
    "recycling_bin": ("non_standard", ("furnishing", "frontage"), (0.7, 0.7, 1.1)),
    "planter": ("non_standard", ("furnishing", "frontage_buffer", "frontage"), (0.9, 0.9, 0.8)),
    "mailbox": ("non_standard", ("furnishing",), (0.5, 0.5, 1.2)),
    "bike_rack": ("non_standard", ("furnishing",), (0.6, 2.0, 0.9)),
    "newspaper_box": ("non_standard", ("furnishing", "frontage"), (0.5, 0.5, 1.1)),
    "vending_machine": ("non_standard", ("frontage",), (0.8, 1.0, 1.9)),
    "phone_booth": ("non_standard", ("furnishing", "frontage"), (1.0, 1.0, 2.3)),
    "bus_shelter": ("non_standard", ("furnishing",), (1.4, 4.0, 2.6)),
    "advertising_board": ("non_standard", ("furnishing", "frontage"), (0.3, 1.4, 2.2)),
    "kiosk": ("non_standard", ("frontage",), (2.0, 2.5, 2.8)),
    "cafe_table": ("non_standard", ("frontage",), (0.8, 0.8, 0.75)),
    "chair": ("non_standard", ("frontage",), (0.5, 0.5, 0.9)),
    "food_cart": ("non_standard", ("frontage", "furnishing"), (1.2, 2.0, 2.0)),
    "street_cabinet": ("non_standard", ("furnishing",), (0.5, 1.0, 1.3)),
    "drinking_fountain": ("non_standard", ("furnishing", "frontage"), (0.5, 0.5, 1.0)),
    "building_facade": ("non_standard", ("building",), (10.0, 12.0, 12.0)),
    "traffic_cone": ("clutter", (), (0.35, 0.35, 0.7)),
    "barrier": ("clutter", (), (0.5, 1.5, 1.0)),
    "bicycle": ("clutter", (), (1.8, 0.6, 1.1)),
    "e_scooter": ("clutter", (), (1.1, 0.5, 1.2)),
    "shopping_bag": ("clutter", (), (0.4, 0.25, 0.45)),
    "cardboard_box": ("clutter", (), (0.5, 0.5, 0.4)),
    "drink_can": ("clutter", (), (0.07, 0.07, 0.12)),
}
ALL_CATEGORIES = tuple(CATEGORIES)
OBJECT_CLASSES = ("standard", "non_standard", "clutter")
CLUTTER_ZONES = ("near_road_buffer", "furnishing", "clear", "frontage_buffer", "frontage")


def by_class(object_class: str, exclude: list[str] | tuple[str, ...] = ()) -> list[str]:
    """Categories of `object_class` (buildings excluded: they have their own pass), minus `exclude`."""
    return [c for c, (k, _, _) in CATEGORIES.items() if k == object_class and c != "building_facade" and c not in exclude]


def _repo_root() -> Path:
    return Path(__file__).resolve().parents[2]


def load_distribution(country: str, path: str | Path) -> dict[str, float]:
    """Category frequencies of `country` from the distribution table (parquet: country, category, count, frequency)."""
    import duckdb

    p = Path(path)
    if not p.is_absolute() and not p.exists() and (_repo_root() / p).exists():
        p = _repo_root() / p
    if not p.exists():
        raise ConfigError(
            f"no category distribution table at {p} (needed for country={country!r}); "
            "run `dvc repro` to build it, or set country to null for uniform categories"
        )
    con = duckdb.connect()
    try:
        rows = con.execute(
            "SELECT country, category, CAST(frequency AS DOUBLE) FROM read_parquet(?) ORDER BY country, category",
            [str(p)],
        ).fetchall()
    finally:
        con.close()
    countries = sorted({r[0] for r in rows})
    freq = {cat: f for c, cat, f in rows if c == country}
    if not freq:
        raise ConfigError(f"country {country!r} is not in {p}; available: {', '.join(countries)}")
    return freq


class CategorySampler:
    """Draws categories per object class from uniform weights or a country's frequencies."""

    def __init__(self, exclude: list[str], frequencies: dict[str, float] | None = None) -> None:
        self.warnings: list[str] = []
        self.weights: dict[str, tuple[list[str], np.ndarray]] = {}
        self._cdf: dict[tuple[str, tuple[str, ...] | None], Any] = {}
        for cls in OBJECT_CLASSES:
            cats = by_class(cls, exclude)
            w = np.ones(len(cats))
            if frequencies is not None:
                w = np.array([max(float(frequencies.get(c, 0.0)), 0.0) for c in cats])
                if w.sum() <= 0:
                    self.warnings.append(f"the distribution has no {cls} category; drawing {cls} categories uniformly")
                    w = np.ones(len(cats))
            self.weights[cls] = (cats, w)

    def draw(self, rng: np.random.Generator, object_class: str, allowed: list[str] | None = None) -> str | None:
        """One category of `object_class` (restricted to `allowed` when given); None when none is allowed."""
        key = (object_class, None if allowed is None else allowed if type(allowed) is tuple else tuple(allowed))
        cdf = self._cdf.get(key)
        if cdf is None:
            made = self._make_cdf(object_class, allowed)
            # The CDF as plain floats: bisect_right on them is c.searchsorted(u, side="right").
            cdf = self._cdf[key] = made if made is False else (made[0], made[1].tolist())
        if cdf is False:
            return None
        cats, c = cdf
        # What rng.choice(len(cats), p=w / w.sum()) does, without its per-call validation (the placer draws
        # thousands of categories per scene): one uniform draw searched in the normalised CDF.
        return cats[bisect_right(c, rng.random())]

    def _make_cdf(self, object_class: str, allowed: list[str] | None) -> tuple[list[str], np.ndarray] | bool:
        cats, w = self.weights[object_class]
        if allowed is not None:
            keep = np.array([c in allowed for c in cats], dtype=bool)
            if not keep.any():
                return False
            w = np.where(keep, w, 0.0)
            if w.sum() <= 0:
                w = keep.astype(np.float64)
        if not cats:
            return False
        c = (w / w.sum()).cumsum()
        c /= c[-1]
        return cats, c


def category_info(category: str) -> dict[str, Any]:
    """Class, zones and fallback size of `category`."""
    cls, zones, size = CATEGORIES[category]
    return {"object_class": cls, "zones": zones, "size": size}
