"""MetaUrban-12K-style scene datasets (train/test/unseen/finetune splits) and their statistics."""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from kernel.config import check_choice

# Categories held out of train/test and seen only in unseen/finetune (with template g); within the other categories a
# fifth of the catalog's assets is held out the same way (catalogs.reader.CatalogReader.asset_split).
HELD_OUT_CATEGORIES = [
    "drinking_fountain",
    "e_scooter",
    "food_cart",
    "kiosk",
    "phone_booth",
    "shopping_bag",
    "vending_machine",
]
SPLITS: dict[str, dict[str, Any]] = {
    "train": {"templates": "abcdef", "exclude_categories": HELD_OUT_CATEGORIES, "assets": "seen", "seed_offset": 0},
    "test": {
        "templates": "abcdef",
        "exclude_categories": HELD_OUT_CATEGORIES,
        "assets": "seen",
        "seed_offset": 1_000_000,
    },
    "unseen": {"templates": "g", "exclude_categories": [], "assets": "held_out", "seed_offset": 2_000_000},
    "finetune": {"templates": "g", "exclude_categories": [], "assets": "held_out", "seed_offset": 3_000_000},
}
SUMMARY_KEYS = (
    "objects",
    "buildings",
    "refused_total",
    "street_length_m",
    "clear_path_length_m",
    "walkable_area_m2",
    "object_area_m2",
    "object_area_fraction",
    "sidewalks",
    "crosswalks",
    "blocks",
)


def split_config(split: str, base: dict[str, Any] | None = None) -> tuple[dict[str, Any], int]:
    """Generator config and seed offset of `split` (seeds of different splits never collide)."""
    check_choice(split, tuple(SPLITS), what="split")
    s = SPLITS[split]
    cfg = dict(base or {})
    cfg["templates"] = s["templates"]
    cfg["exclude_categories"] = sorted(set(cfg.get("exclude_categories", [])) | set(s["exclude_categories"]))
    cfg["assets"] = s["assets"]  # unseen and finetune scenes draw catalog assets train and test never use
    return cfg, int(s["seed_offset"])


def summarize(spec: Mapping[str, Any], file: str, split: str) -> dict[str, Any]:
    """One index row: the scene's id, file, seed and headline statistics."""
    st = spec["stats"]
    row = {"scene_id": Path(file).stem, "file": file, "split": split, "seed": spec["seed"]}
    row.update({k: st[k] for k in SUMMARY_KEYS})
    row.update({f"n_{k}": v for k, v in st["objects_by_class"].items()})
    row["templates"] = "".join(sorted(st["templates"]))
    return row


def _reader(catalog: str | None) -> Any:
    """The catalog reader of this worker process (read once per process, not once per scene)."""
    if catalog is None:
        return None
    from catalogs.reader import read_catalog

    return read_catalog(catalog)


def scene_file(split: str, seed: int) -> str:
    """A scene's file name inside a dataset folder."""
    return f"scenes/{split}_{seed:08d}.json"


def verified_scene(path: Path, seed: int, config: dict[str, Any], catalog: str | None) -> Mapping[str, Any] | None:
    """The spec at `path` when it is a complete scene of this seed, resolved config and catalog, else None.

    Files are written atomically, so a file that parses is whole; the seed, config and catalog checks make a
    rerun with other settings regenerate instead of mixing scenes of two configs in one dataset.
    """
    from sim.scene.scene import Scene

    try:
        spec = Scene.load(path).spec
    except (OSError, ValueError):  # SceneError is a ValueError
        return None
    if spec.get("seed") != seed or spec.get("config") != config or spec.get("catalog") != catalog:
        return None
    if not isinstance(spec.get("stats"), dict) or any(k not in spec["stats"] for k in SUMMARY_KEYS):
        return None
    return spec


def scene_item(seed: int, job: dict[str, Any]) -> tuple[dict[str, Any], str | None]:
    """(index row, canonical JSON to write, or None when the verified file already in the dataset is kept) of one
    seed; runs in any worker, and its answer depends on the seed and `job` alone (a retried seed gives the same)."""
    import warnings

    from sim.scene.generator import generate_scene
    from sim.scene.spec import encode

    name = scene_file(job["split"], seed)
    path = Path(job["out"]) / name
    if path.exists():  # a worker on another node without the shared folder sees no file and generates
        spec = verified_scene(path, seed, job["resolved"], job["catalog"])
        if spec is not None:
            return summarize(spec, name, job["split"]), None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # fallback categories are in each scene's stats; the CLI reports them once
        spec = generate_scene(job["cfg"], seed, _reader(job["catalog"]))
    spec["catalog"] = job["catalog"]  # a str or None: the spec stays canonical
    return summarize(spec, name, job["split"]), encode(spec)


MAX_COUNT = 1_000_000  # splits start 1,000,000 seeds apart


def build_dataset(
    split: str,
    count: int,
    out: str | Path,
    *,
    base: dict[str, Any] | None = None,
    catalog: str | None = None,
    workers: int | None = None,
    progress: Callable[[int], None] | None = None,
    executor: str | None = None,
    address: str | None = None,
    nodes: dict[str, int] | None = None,
) -> list[dict[str, Any]]:
    """Generate `count` scenes of `split` into `out` (one JSON each) plus index.jsonl and index.parquet.

    `executor` (kernel.executors): local, process (`workers` processes) or ray (a cluster at `address`, or one
    started here with `workers` CPUs; None: every core); by default process when workers > 1, else local. Workers
    generate, this
    process writes every file, so the dataset is byte-identical whichever executor ran it. Resumable: scene files
    already in `out` that are complete and match the seed, config and catalog are kept, so a rerun after a kill
    generates only the missing (or corrupt) ones. Index rows follow seed order.
    """
    from kernel.config import ConfigError
    from kernel.executors import run_map
    from sim.scene.config import resolve_config
    from sim.scene.spec import TMP_SUFFIX, canonical, write_atomic

    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_COUNT:
        raise ConfigError(f"count must be an integer in [1, {MAX_COUNT}] (scenes per split), got {count!r}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= 256):
        raise ConfigError(f"workers must be an integer in [1, 256], got {workers!r}")
    cfg, offset = split_config(split, base)
    resolved = canonical(resolve_config(cfg))  # fail before starting workers; as stored in each spec
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{out} is a file; give a folder for the dataset")
    (out / "scenes").mkdir(parents=True, exist_ok=True)
    for tmp in (out / "scenes").glob(f".*{TMP_SUFFIX}"):
        tmp.unlink(missing_ok=True)  # left by a killed run (sim.scene.spec.write_atomic)
    executor = executor or ("process" if workers is not None and workers > 1 else "local")
    job = {"cfg": cfg, "catalog": catalog, "out": str(out.resolve()), "split": split, "resolved": resolved}
    rows: list[dict[str, Any]] = []
    seeds = (offset + i for i in range(count))
    for row, text in run_map(
        scene_item,
        seeds,
        executor=executor,
        workers=workers,
        address=address,
        args=(job,),
        progress=progress,
        nodes=nodes,
    ):
        if text is not None:
            # Atomic: a kill leaves the old file or none, never half a scene. No fsync: after a power loss a file
            # that came back empty or torn fails `verified_scene` on the next run and is generated again.
            write_atomic(out / row["file"], text, durable=False)
        rows.append(row)
    write_index(rows, out)
    return rows


def write_index(rows: list[dict[str, Any]], out: Path) -> None:
    """Write the per-scene summaries as index.jsonl and index.parquet (each atomically)."""
    import os

    import pyarrow as pa
    import pyarrow.parquet as pq

    from sim.scene.spec import write_atomic

    write_atomic(out / "index.jsonl", "".join(json.dumps(r, sort_keys=True) + "\n" for r in rows))
    tmp = out / f".index.parquet.{os.getpid()}.tmp"
    pq.write_table(pa.Table.from_pylist(rows), tmp)
    os.replace(tmp, out / "index.parquet")


def read_index(directory: str | Path) -> list[dict[str, Any]]:
    """Rows of a dataset's index.jsonl (clear error when the folder is not a dataset)."""
    p = Path(directory) / "index.jsonl"
    if not p.exists():
        raise FileNotFoundError(
            f"no index.jsonl in {directory}; create the dataset with `curbside scenes dataset --out {directory}`"
        )
    return [json.loads(line) for line in p.read_text(encoding="utf-8").splitlines() if line.strip()]


def _describe(x: np.ndarray) -> dict[str, float]:
    return {
        "mean": float(x.mean()),
        "std": float(x.std()),
        "min": float(x.min()),
        "p50": float(np.median(x)),
        "max": float(x.max()),
    }


def dataset_stats(directory: str | Path) -> tuple[dict[str, Any], Path, Path]:
    """Statistics of a dataset (objects per scene, area occupied by objects, street length along the blocks) as JSON and PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = Path(directory)
    rows = read_index(d)
    if not rows:
        raise ValueError(f"{d}/index.jsonl lists no scenes; regenerate the dataset")
    cols = {
        k: np.array([r[k] for r in rows], dtype=np.float64)
        for k in (
            "objects",
            "object_area_m2",
            "object_area_fraction",
            "street_length_m",
            "walkable_area_m2",
            "refused_total",
        )
    }
    stats: dict[str, Any] = {"scenes": len(rows), "splits": sorted({r["split"] for r in rows})}
    stats.update({k: _describe(v) for k, v in cols.items()})
    blocks: dict[str, int] = {}
    for r in rows:
        for c in r["blocks"]:
            blocks[c] = blocks.get(c, 0) + 1
    stats["block_types"] = dict(sorted(blocks.items()))
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for ax, key, label in zip(
        axes,
        ("objects", "object_area_m2", "street_length_m"),
        ("objects per scene", "area occupied by objects (m²)", "street length along the blocks (m)"),
    ):
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
