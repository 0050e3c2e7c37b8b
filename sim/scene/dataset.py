"""MetaUrban-12K-style scene datasets (train/test/unseen/finetune splits) and their statistics."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from curbside.config import check_choice

# Categories held out of train/test and seen only in unseen/finetune (with template g).
HELD_OUT_CATEGORIES = ["drinking_fountain", "e_scooter", "food_cart", "kiosk", "phone_booth", "shopping_bag", "vending_machine"]
SPLITS: dict[str, dict[str, Any]] = {
    "train": {"templates": "abcdef", "exclude_categories": HELD_OUT_CATEGORIES, "seed_offset": 0},
    "test": {"templates": "abcdef", "exclude_categories": HELD_OUT_CATEGORIES, "seed_offset": 1_000_000},
    "unseen": {"templates": "g", "exclude_categories": [], "seed_offset": 2_000_000},
    "finetune": {"templates": "g", "exclude_categories": [], "seed_offset": 3_000_000},
}
SUMMARY_KEYS = (
    "objects", "buildings", "refused_total", "route_length_m", "clear_path_length_m",
    "walkable_area_m2", "object_area_m2", "object_area_fraction", "sidewalks", "crosswalks", "blocks",
)


def split_config(split: str, base: dict[str, Any] | None = None) -> tuple[dict[str, Any], int]:
    """Generator config and seed offset of `split` (seeds of different splits never collide)."""
    check_choice(split, tuple(SPLITS), what="split")
    s = SPLITS[split]
    cfg = dict(base or {})
    cfg["templates"] = s["templates"]
    cfg["exclude_categories"] = sorted(set(cfg.get("exclude_categories", [])) | set(s["exclude_categories"]))
    return cfg, int(s["seed_offset"])


def summarize(spec: dict[str, Any], file: str, split: str) -> dict[str, Any]:
    """One index row: the scene's id, file, seed and headline statistics."""
    st = spec["stats"]
    row = {"scene_id": Path(file).stem, "file": file, "split": split, "seed": spec["seed"]}
    row.update({k: st[k] for k in SUMMARY_KEYS})
    row.update({f"n_{k}": v for k, v in st["objects_by_class"].items()})
    row["templates"] = "".join(sorted(st["templates"]))
    return row


_WORKER: dict[str, Any] = {}


def _init(cfg: dict[str, Any], catalog: str | None, out: str, split: str) -> None:
    reader = None
    if catalog is not None:
        from catalogs.reader import CatalogReader

        reader = CatalogReader(catalog)
    _WORKER.update(cfg=cfg, catalog=reader, name=catalog, out=out, split=split)


def _one(seed: int) -> dict[str, Any]:
    import warnings

    from sim.scene.generator import generate_scene
    from sim.scene.spec import save

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # fallback categories are in each scene's stats; the CLI reports them once
        spec = generate_scene(_WORKER["cfg"], seed, _WORKER["catalog"])
    spec["catalog"] = _WORKER["name"]
    name = f"scenes/{_WORKER['split']}_{seed:08d}.json"
    save(spec, Path(_WORKER["out"]) / name)
    return summarize(spec, name, _WORKER["split"])


def build_dataset(
    split: str, count: int, out: str | Path, *, base: dict[str, Any] | None = None, catalog: str | None = None,
    workers: int = 1, progress: Callable[[int], None] | None = None,
) -> list[dict[str, Any]]:
    """Generate `count` scenes of `split` into `out` (one JSON each) plus index.jsonl and index.parquet."""
    from sim.scene.config import resolve_config

    cfg, offset = split_config(split, base)
    resolve_config(cfg)  # fail before starting workers
    out = Path(out)
    (out / "scenes").mkdir(parents=True, exist_ok=True)
    seeds = [offset + i for i in range(count)]
    rows: list[dict[str, Any]] = []
    if workers <= 1:
        _init(cfg, catalog, str(out), split)
        for s in seeds:
            rows.append(_one(s))
            if progress:
                progress(1)
    else:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(workers, initializer=_init, initargs=(cfg, catalog, str(out), split)) as pool:
            for row in pool.imap(_one, seeds, chunksize=8):
                rows.append(row)
                if progress:
                    progress(1)
    write_index(rows, out)
    return rows


def write_index(rows: list[dict[str, Any]], out: Path) -> None:
    """Write the per-scene summaries as index.jsonl and index.parquet."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    with open(out / "index.jsonl", "w", encoding="utf-8") as f:
        for r in rows:
            f.write(json.dumps(r, sort_keys=True) + "\n")
    pq.write_table(pa.Table.from_pylist(rows), out / "index.parquet")


def read_index(directory: str | Path) -> list[dict[str, Any]]:
    """Rows of a dataset's index.jsonl (clear error when the folder is not a dataset)."""
    p = Path(directory) / "index.jsonl"
    if not p.exists():
        raise FileNotFoundError(f"no index.jsonl in {directory}; create the dataset with `curbside scenes dataset --out {directory}`")
    return [json.loads(line) for line in p.read_text(encoding="utf-8").splitlines() if line.strip()]


def _describe(x: np.ndarray) -> dict[str, float]:
    return {"mean": float(x.mean()), "std": float(x.std()), "min": float(x.min()), "p50": float(np.median(x)), "max": float(x.max())}


def dataset_stats(directory: str | Path) -> tuple[dict[str, Any], Path, Path]:
    """Statistics of a dataset (objects per scene, area occupied by objects, route length) as JSON and PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = Path(directory)
    rows = read_index(d)
    if not rows:
        raise ValueError(f"{d}/index.jsonl lists no scenes; regenerate the dataset")
    cols = {k: np.array([r[k] for r in rows], dtype=np.float64) for k in (
        "objects", "object_area_m2", "object_area_fraction", "route_length_m", "walkable_area_m2", "refused_total")}
    stats: dict[str, Any] = {"scenes": len(rows), "splits": sorted({r["split"] for r in rows})}
    stats.update({k: _describe(v) for k, v in cols.items()})
    blocks: dict[str, int] = {}
    for r in rows:
        for c in r["blocks"]:
            blocks[c] = blocks.get(c, 0) + 1
    stats["block_types"] = dict(sorted(blocks.items()))
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for ax, key, label in zip(axes, ("objects", "object_area_m2", "route_length_m"),
                              ("objects per scene", "area occupied by objects (m²)", "route length (m)")):
        ax.hist(cols[key], bins=min(30, max(5, len(rows) // 3)), color="#1565c0", alpha=0.85)
        ax.axvline(cols[key].mean(), color="#e65100", lw=1.2, label=f"mean {cols[key].mean():.1f}")
        ax.set_xlabel(label)
        ax.set_ylabel("scenes")
        ax.legend(fontsize=8)
    fig.suptitle(f"{d.name}: {len(rows)} scenes ({', '.join(stats['splits'])})", fontsize=10)
    fig.tight_layout()
    png, js = d / "stats.png", d / "stats.json"
    fig.savefig(png, dpi=120)
    plt.close(fig)
    js.write_text(json.dumps(stats, indent=2, sort_keys=True), encoding="utf-8")
    return stats, png, js
