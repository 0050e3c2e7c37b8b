"""Stage `distribution`: per-country and global category frequencies, the table the scene generator reads."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pipelines.common import REPO_ROOT, PipelineError, load_params, stage_cli, write_metrics, write_table
from pipelines.countries import GLOBAL, check_country

DEFAULT_PATH = REPO_ROOT / "data" / "distribution" / "distribution.parquet"
COLUMNS = ["country", "category", "count", "frequency"]


def compute_distribution(descriptions: Any, sources: list[str]) -> Any:
    """Pure function of the stage: rows (country, category, count, frequency); frequencies sum to 1 per country."""
    import pandas as pd

    obs = descriptions[descriptions["source"].isin(sources) & descriptions["country"].notna()]
    per = obs.groupby(["country", "category"])["count"].sum().reset_index()
    glob = per.groupby("category")["count"].sum().reset_index()
    glob.insert(0, "country", GLOBAL)
    df = pd.concat([per, glob], ignore_index=True)
    df["count"] = df["count"].astype("int64")
    df["frequency"] = df["count"] / df.groupby("country")["count"].transform("sum")
    df = df[df["count"] > 0].sort_values(["country", "count", "category"], ascending=[True, False, True])
    return df[COLUMNS].reset_index(drop=True)


def load_distribution(country: str, path: str | Path = DEFAULT_PATH) -> dict[str, float]:
    """Category -> frequency for an ISO alpha-2 country (or 'GLOBAL') from distribution.parquet."""
    import pandas as pd

    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(
            f"{p} does not exist; run `dvc repro distribution` (or `python -m pipelines.distribution`)"
        )
    code = GLOBAL if str(country).upper() == GLOBAL else check_country(country, where="load_distribution")
    df = pd.read_parquet(p)
    sel = df[df["country"] == code]
    if sel.empty:
        have = ", ".join(sorted(set(df["country"])))
        raise KeyError(f"no distribution for {code} in {p}; available: {have}; add an OSM extract or images for it")
    return {str(c): float(f) for c, f in zip(sel["category"], sel["frequency"], strict=True)}


def plot_distribution(df: Any, path: str | Path, top: int = 20) -> Path:
    """Horizontal bar chart per country (top categories), written as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    countries = list(dict.fromkeys(df["country"]))
    fig, axes = plt.subplots(1, len(countries), figsize=(5 * len(countries), 6), squeeze=False)
    for ax, c in zip(axes[0], countries, strict=True):
        sel = df[df["country"] == c].head(top).iloc[::-1]
        ax.barh(sel["category"], sel["frequency"], color="#3b7dd8")
        ax.set_title(f"{c}: {int(df.loc[df['country'] == c, 'count'].sum())} objects")
        ax.set_xlabel("frequency")
    fig.suptitle("Street-object category frequencies")
    fig.tight_layout()
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def run(params_path: str | None = None) -> dict[str, Any]:
    """Stage entry: write distribution.parquet, plot.csv and distribution.png (dvc plots) and metrics.json."""
    import pandas as pd

    p = load_params(params_path, "distribution")
    bad = sorted(set(p["sources"]) - {"osm", "images", "closed_set"})
    if bad:
        raise PipelineError(f"unknown distribution.sources {bad}; valid: osm, images")
    df = compute_distribution(pd.read_parquet(p["descriptions"]), list(p["sources"]))
    out = Path(p["out_dir"])
    write_table(df, out / "distribution.parquet")
    df.to_csv(out / "plot.csv", index=False, float_format="%.6f")
    if len(df):
        plot_distribution(df, out / "distribution.png")
    countries = sorted(set(df["country"]) - {GLOBAL})
    metrics: dict[str, Any] = {"countries": len(countries), "categories_global": int((df["country"] == GLOBAL).sum())}
    for c in countries:
        metrics[f"objects_{c}"] = int(df.loc[df["country"] == c, "count"].sum())
    write_metrics(out / "metrics.json", metrics)
    return metrics


if __name__ == "__main__":
    stage_cli("distribution", run)
