"""Stage `closed_set`: the sidewalk object classes of Cityscapes / Mapillary Vistas and street-design handbooks."""

from __future__ import annotations

from pathlib import Path

from catalogs.categories import CATEGORIES, check_category
from pipelines.common import PipelineError, load_params, stage_cli, write_metrics, write_table

COLUMNS = ["source", "name", "category", "group", "prompt", "provenance"]


def _read_csv(path: str | Path, required: list[str]):  # noqa: ANN202 - pandas.DataFrame
    import pandas as pd

    p = Path(path)
    if not p.exists():
        raise PipelineError(f"closed-set list {p} not found; set closed_set paths in params.yaml to existing CSV files")
    df = pd.read_csv(p, dtype=str, keep_default_na=False)
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise PipelineError(f"{p} lacks column(s) {', '.join(missing)}; expected {', '.join(required)}")
    empty = df.index[(df["provenance"].str.strip() == "")].tolist()
    if empty:
        raise PipelineError(f"{p}: rows {empty} have no provenance; every closed-set class must cite its source")
    for i, cat in enumerate(df["category"]):
        check_category(cat, where=f"{p} row {i + 2}")
    return df


def load_closed_set(segmentation_csv: str | Path, handbook_csv: str | Path):  # noqa: ANN201 - pandas.DataFrame
    """Read and validate both closed-set lists into one table (source, name, category, group, prompt, provenance)."""
    import pandas as pd

    seg = _read_csv(segmentation_csv, ["source", "class_name", "category", "prompt", "provenance"])
    seg = seg.rename(columns={"class_name": "name"})
    hb = _read_csv(handbook_csv, ["name", "category", "prompt", "provenance"])
    hb.insert(0, "source", "handbook")
    df = pd.concat([seg, hb], ignore_index=True)
    df["group"] = [CATEGORIES[c].object_class for c in df["category"]]
    dup = df[df.duplicated(["source", "name"])]
    if len(dup):
        raise PipelineError(f"closed-set lists repeat (source, name) {dup[['source', 'name']].values.tolist()}")
    return df[COLUMNS].sort_values(["source", "category", "name"]).reset_index(drop=True)


def run(params_path: str | None = None) -> dict[str, int]:
    """Stage entry: write data/closed_set/classes.parquet and metrics.json; returns the metrics."""
    p = load_params(params_path, "closed_set")
    df = load_closed_set(p["segmentation_csv"], p["handbook_csv"])
    out = Path(p["out_dir"])
    write_table(df, out / "classes.parquet")
    metrics = {
        "classes": len(df),
        "handbook_objects": int((df["source"] == "handbook").sum()),
        "segmentation_classes": int((df["source"] != "handbook").sum()),
        "categories_covered": int(df["category"].nunique()),
        "categories_total": len(CATEGORIES),
    }
    write_metrics(out / "metrics.json", metrics)
    return metrics


if __name__ == "__main__":
    stage_cli("closed_set", run)
