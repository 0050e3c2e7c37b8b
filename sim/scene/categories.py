"""Category draws for the scene generator: per-class samplers over catalogs/categories.csv and country frequencies."""

from __future__ import annotations

from bisect import bisect_right
from pathlib import Path
from typing import Any, Literal

import numpy as np

from catalogs.categories import of_class
from catalogs.schema import OBJECT_CLASSES
from kernel.config import ConfigError


def by_class(object_class: str, exclude: list[str] | tuple[str, ...] = ()) -> list[str]:
    """Categories of `object_class` (buildings excluded: they have their own pass), minus `exclude`."""
    return [c for c in of_class(object_class) if c != "building_facade" and c not in exclude]


def _repo_root() -> Path:
    return Path(__file__).resolve().parents[2]


def load_distribution(country: str, path: str | Path) -> dict[str, float]:
    """Category frequencies of `country` from the distribution table (parquet: country, category, count, frequency)."""
    import duckdb

    file_path = Path(path)
    if not file_path.is_absolute() and not file_path.exists() and (_repo_root() / file_path).exists():
        file_path = _repo_root() / file_path
    if not file_path.exists():
        raise ConfigError(
            f"no category distribution table at {file_path} (needed for country={country!r}); "
            "run `dvc repro` to build it, or set country to null for uniform categories"
        )
    con = duckdb.connect()
    try:
        rows = con.execute(
            "SELECT country, category, CAST(frequency AS DOUBLE) FROM read_parquet(?) ORDER BY country, category",
            [str(file_path)],
        ).fetchall()
    finally:
        con.close()
    countries = sorted({row[0] for row in rows})
    freq = {cat: f for c, cat, f in rows if c == country}
    if not freq:
        raise ConfigError(f"country {country!r} is not in {file_path}; available: {', '.join(countries)}")
    return freq


_Cdf = tuple[list[str], np.ndarray, list[float]]  # categories, their normalised CDF, the CDF as floats


class CategorySampler:
    """Draws categories per object class from uniform weights or a country's frequencies."""

    def __init__(self, exclude: list[str], frequencies: dict[str, float] | None = None) -> None:
        self.warnings: list[str] = []
        self.weights: dict[str, tuple[list[str], np.ndarray]] = {}
        self._cdf: dict[tuple[str, tuple[str, ...] | None], _Cdf | Literal[False]] = {}  # False: none allowed
        for cls in OBJECT_CLASSES:
            cats = by_class(cls, exclude)
            weights = np.ones(len(cats))
            if frequencies is not None:
                weights = np.array([max(float(frequencies.get(cat, 0.0)), 0.0) for cat in cats])
                if weights.sum() <= 0:
                    self.warnings.append(f"the distribution has no {cls} category; drawing {cls} categories uniformly")
                    weights = np.ones(len(cats))
            self.weights[cls] = (cats, weights)

    def draw(self, rng: np.random.Generator, object_class: str, allowed: list[str] | None = None) -> str | None:
        """One category of `object_class` (restricted to `allowed` when given); None when none is allowed."""
        made = self._cdf_of(object_class, allowed)
        if made is None:
            return None
        # What rng.choice(len(cats), p=w / w.sum()) does, without its per-call validation (the placer draws
        # thousands of categories per scene): one uniform draw searched in the normalised CDF.
        return made[0][bisect_right(made[2], rng.random())]

    def cdf(self, object_class: str, allowed: tuple[str, ...] | None = None) -> tuple[list[str], np.ndarray] | None:
        """(categories, normalised CDF) that `draw` searches one uniform draw in; None when none is allowed."""
        made = self._cdf_of(object_class, allowed)
        return None if made is None else (made[0], made[1])

    def _cdf_of(self, object_class: str, allowed: Any) -> _Cdf | None:
        key = (object_class, None if allowed is None else allowed if type(allowed) is tuple else tuple(allowed))
        cdf = self._cdf.get(key)
        if cdf is None:
            made = self._make_cdf(object_class, allowed)
            # The CDF also as plain floats: bisect_right on them is c.searchsorted(u, side="right").
            cdf = self._cdf[key] = False if made is False else (made[0], made[1], made[1].tolist())
        return cdf or None

    def _make_cdf(self, object_class: str, allowed: list[str] | None) -> tuple[list[str], np.ndarray] | Literal[False]:
        cats, weights = self.weights[object_class]
        if allowed is not None:
            keep = np.array([cat in allowed for cat in cats], dtype=bool)
            if not keep.any():
                return False
            weights = np.where(keep, weights, 0.0)
            if weights.sum() <= 0:
                weights = keep.astype(np.float64)
        if not cats:
            return False
        cat = (weights / weights.sum()).cumsum()
        cat /= cat[-1]
        return cats, cat
