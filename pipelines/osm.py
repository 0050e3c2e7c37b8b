"""Stage `osm`: street-furniture counts and along-street spacing from OpenStreetMap .osm.pbf extracts (pyosmium)."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from catalogs.categories import check_category
from pipelines.common import (
    PipelineError,
    load_params,
    progress,
    stage_cli,
    write_metrics,
    write_table,
)
from pipelines.countries import check_country

EARTH_RADIUS_M = 6_371_008.8
# Tags copied to each object: they feed the textual description (colour, material, shape).
ATTRIBUTE_TAGS = (
    "colour",
    "material",
    "support",
    "backrest",
    "leaf_type",
    "leaf_cycle",
    "genus",
    "lamp_mount",
    "vending",
    "shelter",
    "bicycle_parking",
    "height",
    "advertising",
    "street_cabinet",
)


def default_extract() -> Path:
    """Path of the Helsinki extract bundled with the pipelines (pipelines/data/README.md says where it comes from)."""
    return Path(__file__).resolve().parent / "data" / "Helsinki.osm.pbf"


@dataclass
class TagRule:
    """One row of the OSM tag -> category table; a rule with an extra condition outranks a plain one.

    `category` None: an open-vocabulary object (a statue, a street clock) outside the category table; `label`
    says what it is. A label on a categorised rule names the object more precisely ("stop sign").
    """

    key: str
    value: str
    extra_key: str
    extra_value: str
    category: str | None
    label: str = ""

    def matches(self, tags: Any) -> bool:
        """True when the tags carry key=value (value '*' = any) and the extra condition, if any."""
        v = tags.get(self.key)
        if v is None or (self.value != "*" and v != self.value):
            return False
        return not self.extra_key or tags.get(self.extra_key) == self.extra_value


def load_tag_rules(path: str | Path) -> list[TagRule]:
    """Read the OSM tag -> category CSV: categorised rules first, within them those with an extra condition."""
    import pandas as pd

    p = Path(path)
    if not p.exists():
        raise PipelineError(f"OSM tag table {p} not found; set osm.tags_csv to catalogs/closed_set/osm_tags.csv")
    df = pd.read_csv(p, dtype=str, keep_default_na=False)
    need = ["key", "value", "extra_key", "extra_value", "category", "label", "provenance"]
    missing = [c for c in need if c not in df.columns]
    if missing:
        raise PipelineError(f"{p} lacks column(s) {', '.join(missing)}")
    rules = []
    for i, r in enumerate(df.itertuples()):
        if not r.category and not r.label:
            raise PipelineError(
                f"{p} row {i + 2}: give a category or, for an object outside the category table, "
                f"a label saying what it is"
            )
        cat = check_category(r.category, where=f"{p} row {i + 2}") if r.category else None
        rules.append(TagRule(r.key, r.value, r.extra_key, r.extra_value, cat, r.label))
    # A categorised rule outranks an open-vocabulary one (a memorial bench is a bench), then conditions first.
    return sorted(rules, key=lambda r: (r.category is None, r.extra_key == "", r.value == "*"))


@dataclass
class ExtractData:
    """What one pass over a PBF yields: categorised nodes, street polylines, and the countries it names."""

    objects: list[dict[str, Any]] = field(default_factory=list)
    streets: list[np.ndarray] = field(default_factory=list)
    countries: Counter = field(default_factory=Counter)


def read_extract(path: str | Path, rules: list[TagRule], street_highways: list[str]) -> ExtractData:
    """Scan a .osm.pbf once: street-furniture nodes, highway ways with node locations, country boundaries."""
    import osmium

    p = Path(path)
    if not p.exists():
        raise PipelineError(f"OSM extract {p} not found; download a Geofabrik .osm.pbf and set osm.extracts[].path")
    keys = {r.key for r in rules}
    streets_set = set(street_highways)
    data = ExtractData()
    try:
        fp: Any = osmium.FileProcessor(str(p)).with_locations()  # yields nodes, ways and relations alike
        for obj in fp:
            if obj.is_node():
                if not any(k in obj.tags for k in keys):
                    continue
                rule = next((r for r in rules if r.matches(obj.tags)), None)
                if rule is None or not obj.location.valid():
                    continue
                row = {
                    "osm_id": int(obj.id),
                    "lon": obj.location.lon,
                    "lat": obj.location.lat,
                    "category": rule.category,
                    "label": rule.label or None,
                    "tag": f"{rule.key}={obj.tags.get(rule.key)}",
                }
                row.update({t: obj.tags.get(t) for t in ATTRIBUTE_TAGS})
                data.objects.append(row)
            elif obj.is_way():
                if obj.tags.get("highway") not in streets_set:
                    continue
                pts = [(n.lon, n.lat) for n in obj.nodes if n.location.valid()]
                if len(pts) >= 2:
                    data.streets.append(np.asarray(pts, dtype=np.float64))
            elif obj.is_relation() and obj.tags.get("admin_level") == "2":
                code = obj.tags.get("ISO3166-1:alpha2") or obj.tags.get("ISO3166-1")
                if code:
                    data.countries[code.upper()] += 1
    except RuntimeError as exc:
        raise PipelineError(
            f"cannot read OSM extract {p}: {exc}; the file is corrupt or not a .osm.pbf (re-download it)"
        ) from None
    return data


def resolve_country(declared: str, found: Counter, path: Path) -> str:
    """The extract's country: the declared ISO code, or with 'auto' the admin_level=2 boundary it contains."""
    if str(declared).lower() != "auto":
        return check_country(declared, where=f"osm.extracts country for {path.name}")
    if not found:
        raise PipelineError(
            f"cannot tell the country of {path.name}: it holds no admin_level=2 boundary with an ISO3166-1 tag; "
            f"set country: <ISO alpha-2 code> for this extract in params.yaml"
        )
    return check_country(found.most_common(1)[0][0], where=f"boundary relation in {path.name}")


def _ecef(lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
    lo, la = np.radians(lon), np.radians(lat)
    return np.column_stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)]) * EARTH_RADIUS_M


def nearest_neighbour_m(lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
    """Distance in metres from each point to its nearest other point (chord on the sphere: exact at street scale)."""
    from scipy.spatial import cKDTree

    if len(lon) < 2:
        return np.zeros(0)
    xyz = _ecef(np.asarray(lon), np.asarray(lat))
    d, _ = cKDTree(xyz).query(xyz, k=2)
    return d[:, 1]


def along_street_gaps(
    objects: Any, streets: list[np.ndarray], *, snap_m: float, max_gap_m: float, tile_deg: float
) -> dict[str, list[float]]:
    """Gaps (m) between consecutive same-category objects along the street each one snaps to, per category."""
    import shapely

    gaps: dict[str, list[float]] = {}
    if len(objects) == 0 or not streets:
        return gaps
    lon, lat = objects["lon"].to_numpy(), objects["lat"].to_numpy()
    cats = objects["category"].to_numpy()
    tiles = np.floor(np.column_stack([lon, lat]) / tile_deg).astype(np.int64)
    bbox = np.array([[s[:, 0].min(), s[:, 1].min(), s[:, 0].max(), s[:, 1].max()] for s in streets])
    margin = snap_m / 111_000.0 * 4
    positions: list[tuple[int, str, float]] = []  # (street index, category, position along street)
    for tile in np.unique(tiles, axis=0):
        sel = np.all(tiles == tile, axis=1)
        lo0, la0 = (tile + 0.5) * tile_deg
        # A local tangent plane per tile keeps metric distortion under ~1 % at any latitude.
        kx, ky = np.radians(1) * EARTH_RADIUS_M * np.cos(np.radians(la0)), np.radians(1) * EARTH_RADIUS_M
        x0, y0, x1, y1 = tile[0] * tile_deg, tile[1] * tile_deg, (tile[0] + 1) * tile_deg, (tile[1] + 1) * tile_deg
        near = np.flatnonzero(
            (bbox[:, 2] >= x0 - margin)
            & (bbox[:, 0] <= x1 + margin)
            & (bbox[:, 3] >= y0 - margin)
            & (bbox[:, 1] <= y1 + margin)
        )
        if len(near) == 0:
            continue
        lines = np.array(
            [
                shapely.LineString(np.column_stack([(streets[i][:, 0] - lo0) * kx, (streets[i][:, 1] - la0) * ky]))
                for i in near
            ]
        )
        pts = shapely.points((lon[sel] - lo0) * kx, (lat[sel] - la0) * ky)
        tree = shapely.STRtree(lines)
        pi, li = tree.query_nearest(pts, max_distance=snap_m, all_matches=False)
        s = shapely.line_locate_point(lines[li], pts[pi])
        for street, cat, pos in zip(near[li], cats[sel][pi], s, strict=True):
            positions.append((int(street), str(cat), float(pos)))
    positions.sort()
    for (street, cat, pos), (street2, cat2, pos2) in zip(positions, positions[1:], strict=False):
        if street == street2 and cat == cat2 and 0 < pos2 - pos <= max_gap_m:
            gaps.setdefault(cat, []).append(pos2 - pos)
    return gaps


def _stats(values: np.ndarray) -> dict[str, float]:
    v = np.asarray(values, dtype=np.float64)
    return {
        "n": int(len(v)),
        "mean_m": float(v.mean()),
        "median_m": float(np.median(v)),
        "p10_m": float(np.percentile(v, 10)),
        "p90_m": float(np.percentile(v, 90)),
    }


def extract_osm(
    extracts: list[dict[str, Any]],
    rules: list[TagRule],
    *,
    street_highways: list[str],
    snap_m: float,
    max_gap_m: float,
    tile_deg: float,
) -> tuple[Any, Any, Any]:
    """Pure function of the stage: (objects, counts per country/region/category, spacing statistics) tables."""
    import pandas as pd

    obj_frames, spacing_rows = [], []
    with progress() as bar:
        task = bar.add_task("osm extracts", total=len(extracts))
        for i, ex in enumerate(extracts):
            unknown = set(ex) - {"path", "country", "region"}
            if unknown:
                raise PipelineError(
                    f"osm.extracts[{i}] has unknown key(s) {sorted(unknown)}; valid: path, country, region"
                )
            path = Path(ex.get("path") or default_extract())
            data = read_extract(path, rules, street_highways)
            country = resolve_country(ex.get("country", "auto"), data.countries, path)
            region = ex.get("region") or path.name.split(".")[0]
            df = pd.DataFrame(
                data.objects, columns=["osm_id", "lon", "lat", "category", "label", "tag", *ATTRIBUTE_TAGS]
            )
            df.insert(0, "region", region)
            df.insert(0, "country", country)
            df = df.sort_values("osm_id", kind="stable").reset_index(drop=True)
            obj_frames.append(df)
            # Spacing and counts are per category: open-vocabulary objects (category None) feed descriptions only.
            gaps = along_street_gaps(
                df[df["category"].notna()], data.streets, snap_m=snap_m, max_gap_m=max_gap_m, tile_deg=tile_deg
            )
            for cat, g in sorted(gaps.items()):
                spacing_rows.append(
                    {
                        "country": country,
                        "region": region,
                        "category": cat,
                        "method": "along_street",
                        **_stats(np.asarray(g)),
                    }
                )
            for cat, grp in df.groupby("category", sort=True):
                nn = nearest_neighbour_m(grp["lon"].to_numpy(), grp["lat"].to_numpy())
                if len(nn):
                    spacing_rows.append(
                        {
                            "country": country,
                            "region": region,
                            "category": cat,
                            "method": "nearest_neighbour",
                            **_stats(nn),
                        }
                    )
            bar.advance(task)
    objects = pd.concat(obj_frames, ignore_index=True)
    counts = (
        objects.groupby(["country", "region", "category"])
        .size()
        .rename("count")
        .reset_index()
        .sort_values(["country", "region", "count", "category"], ascending=[True, True, False, True])
    )
    spacing = pd.DataFrame(
        spacing_rows, columns=["country", "region", "category", "method", "n", "mean_m", "median_m", "p10_m", "p90_m"]
    )
    return objects, counts.reset_index(drop=True), spacing


def run(params_path: str | None = None) -> dict[str, int]:
    """Stage entry: write data/osm/{objects,counts,spacing}.parquet, spacing.csv (plot) and metrics.json."""
    p = load_params(params_path, "osm")
    if not p["extracts"]:
        raise PipelineError("osm.extracts is empty; list at least one extract (path may be '' for Helsinki)")
    rules = load_tag_rules(p["tags_csv"])
    objects, counts, spacing = extract_osm(
        p["extracts"],
        rules,
        street_highways=list(p["street_highways"]),
        snap_m=float(p["snap_distance_m"]),
        max_gap_m=float(p["max_gap_m"]),
        tile_deg=float(p["tile_deg"]),
    )
    out = Path(p["out_dir"])
    write_table(objects, out / "objects.parquet")
    write_table(counts, out / "counts.parquet")
    write_table(spacing, out / "spacing.parquet")
    along = spacing[spacing["method"] == "along_street"][["country", "category", "n", "median_m"]]
    along.to_csv(out / "spacing.csv", index=False, float_format="%.2f")
    metrics = {
        "extracts": len(p["extracts"]),
        "objects": len(objects),
        "countries": int(objects["country"].nunique()),
        "categories": int(objects["category"].nunique()),
        "open_vocabulary_objects": int(objects["category"].isna().sum()),
        "spacing_gaps_along_street": int(spacing.loc[spacing["method"] == "along_street", "n"].sum()),
    }
    write_metrics(out / "metrics.json", metrics)
    return metrics


if __name__ == "__main__":
    stage_cli("osm", run)
