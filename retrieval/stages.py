"""The asset half as DVC stages: normalise -> render -> score -> curate, each a function over files.

Each stage runs one step of `retrieval.steps` (the same code `ingest.process_item` fuses per asset) over every
item and hands its state to the next stage through a folder and a parquet table, one row per asset; an asset
rejected by a stage keeps its row (stage, reason, detail) so `curate` records it. Run one stage with
`python -m retrieval.stages <stage> --params retrieval/params.yaml [--root outputs/retrieval]`.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import traceback
from collections.abc import Callable, Iterator
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from curbside.config import ConfigError
from curbside.reproducible import quiet_third_party, write_frame, write_parquet
from retrieval.ingest import IngestConfig, ItemResult, config_from_dict
from retrieval.normalize import AssetRejected, CanonicalMesh
from retrieval.scoring import AssetScores, DescriptionPool
from retrieval.sources import Source, SourceItem
from retrieval.steps import (
    Rendered,
    asset_dir_for,
    asset_id_for,
    curate_step,
    normalise_step,
    render_step,
    score_step,
    view_records,
)

# The params.yaml sections each stage reads; dvc.yaml lists exactly these (a test checks it).
STAGE_PARAMS: dict[str, tuple[str, ...]] = {
    "normalise": ("source", "normalise"), "render": ("render",), "score": ("score",), "curate": ("score", "curate"),
}
# Which IngestConfig fields each section sets (normalise -> QualityLimits, score -> ScoringConfig).
_SECTION_FIELDS = {"render": ("n_views", "n_informative", "image_size", "elevations"),
                   "curate": ("collision", "dedupe_threshold", "write_glb")}
_REJECT_COLS = ("stage", "reason", "detail")


def config_for(params: dict[str, Any], stage: str | None = None) -> IngestConfig:
    """IngestConfig from only the sections `stage` declares (others keep defaults; None: all), strict about keys."""
    d: dict[str, Any] = {}
    sections = STAGE_PARAMS[stage] if stage else dict.fromkeys(s for v in STAGE_PARAMS.values() for s in v)
    for sec in sections:
        values = params.get(sec) or {}
        if sec == "normalise":
            d["limits"] = values.get("limits") or {}
        elif sec == "score":
            d["scoring"] = values
        elif sec in _SECTION_FIELDS:
            bad = sorted(set(values) - set(_SECTION_FIELDS[sec]))
            if bad:
                raise ValueError(f"unknown keys {bad} in params section {sec!r}; valid: {_SECTION_FIELDS[sec]}")
            d.update(values)
    return config_from_dict(d)


def stage_pool() -> DescriptionPool:
    """The pool the stages match against: the category prompts, as for ingest into a fresh catalog."""
    from retrieval.curation import load_size_priors
    from retrieval.scoring import category_pool

    return category_pool(sorted(load_size_priors()))


def _guard(stage: str, fn: Callable[..., Any], *args: Any) -> tuple[Any, dict[str, str] | None]:
    """Run one step; a bad asset becomes (None, rejection columns) instead of stopping the stage."""
    try:
        return fn(*args), None
    except AssetRejected as rej:
        return None, {"stage": stage, "reason": rej.reason, "detail": rej.detail}
    except ConfigError:
        raise  # wrong for every asset: stop the stage rather than reject them all
    except Exception as exc:  # noqa: BLE001 - one broken asset must never stop the stage; the reason is kept
        tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
        return None, {"stage": stage, "reason": "error", "detail": tb[:400]}


def _item(row: dict[str, Any]) -> SourceItem:
    """The source item a manifest row was made from."""
    return SourceItem(**json.loads(row["item"]))


def _rejected(row: dict[str, Any] | None) -> bool:
    """Whether a table row records a rejection (a null reason reads back as None or NaN)."""
    return row is not None and isinstance(row.get("reason"), str)


def _live(df: pd.DataFrame) -> Iterator[dict[str, Any]]:
    """Rows of the assets this table did not reject."""
    return (row for row in df.to_dict("records") if not _rejected(row))


def _write(rows: list[dict[str, Any]], path: Path) -> None:
    """Write one parquet table (rows in item order, rejection columns always present)."""
    df = pd.DataFrame(rows)
    for c in ("asset_id", *_REJECT_COLS):
        if c not in df:
            df[c] = None
    write_frame(df, path)  # fixed writer settings: the same rows give the same bytes (dvc.lock stays put)


def _save_canon(canon: CanonicalMesh, out: Path) -> None:
    """Keep the canonical mesh losslessly (the OBJ is rounded and unwelded), for curate to scale and export."""
    arrays = {"vertices": canon.mesh.vertices, "faces": canon.mesh.faces, "face_colors": canon.face_colors}
    if canon.uv is not None:
        arrays["uv"] = canon.uv
    np.savez(out / "canonical.npz", **arrays)
    if canon.texture_image is not None:
        canon.texture_image.save(out / "canonical_texture.png")


def _load_canon(out: Path, up_axis: str, params: dict[str, Any]) -> CanonicalMesh:
    """The canonical mesh `_save_canon` wrote."""
    import trimesh
    from PIL import Image

    z = np.load(out / "canonical.npz")
    mesh = trimesh.Trimesh(z["vertices"], z["faces"], process=False)
    tex = out / "canonical_texture.png"
    return CanonicalMesh(mesh, z["face_colors"], up_axis, Image.open(tex) if tex.exists() else None,
                         z.get("uv"), params)


def normalise(source: Source, config: IngestConfig, out_dir: Path, manifest: Path, limit: int | None = None) -> int:
    """Fetch every item and normalise it into `out_dir`; writes the manifest; returns the number kept."""
    rows = []
    for item in source.items(limit):
        row: dict[str, Any] = {"asset_id": asset_id_for(item), "content_hash": item.content_hash(),
                               "item": json.dumps(asdict(item), sort_keys=True)}
        if "rejected" in item.metadata:  # refused by the source's prefilter (licence, annotated size, download)
            reason, detail = item.metadata["rejected"]
            rows.append({**row, "stage": "fetch", "reason": reason, "detail": detail})
            continue
        out = asset_dir_for(item, out_dir)
        norm, rej = _guard("normalize", normalise_step, item, config, out)
        if rej:
            rows.append({**row, **rej})
            continue
        _save_canon(norm.canon, out)
        rows.append({**row, "obj": norm.obj.relative_to(out_dir).as_posix(), "up_axis": norm.canon.up_axis,
                     "bounds": norm.canon.mesh.bounds.ravel().tolist(), "params": json.dumps(norm.canon.params)})
    _write(rows, manifest)
    return sum(not _rejected(r) for r in rows)


def render(manifest: Path, normalised_dir: Path, config: IngestConfig, views_dir: Path, views: Path) -> int:
    """Render every normalised asset into `views_dir`; writes the views table; returns the number kept."""
    rows = []
    for row in _live(pd.read_parquet(manifest)):
        item, out = _item(row), asset_dir_for(_item(row), views_dir)
        bounds = np.asarray(row["bounds"], dtype=np.float64).reshape(2, 3)
        r, rej = _guard("render", render_step, item, normalised_dir / row["obj"], bounds, config, out)
        base = {"asset_id": row["asset_id"]}
        rows.append({**base, **rej} if rej else {
            **base, "files": [f.relative_to(views_dir).as_posix() for f in r.files], "azimuths": r.azimuths,
            "elevations": r.elevations, "selected": r.selected, "info": r.info})
    _write(rows, views)
    return sum(not _rejected(r) for r in rows)


def _vec(v: np.ndarray | None) -> list[float] | None:
    """A vector as a parquet list (float64 holds float32 values exactly)."""
    return None if v is None else np.asarray(v, dtype=np.float64).tolist()


def _dtype(v: np.ndarray | None) -> str | None:
    """The vector's dtype, so curate restores the array the scorer made."""
    return None if v is None else str(np.asarray(v).dtype)


def score(manifest: Path, views: Path, views_dir: Path, config: IngestConfig, scores: Path) -> int:
    """Score every rendered asset's informative views and metadata; writes the scores table; returns the count."""
    from PIL import Image

    pool, rows = stage_pool(), []
    items = {r["asset_id"]: _item(r) for r in pd.read_parquet(manifest).to_dict("records")}
    for row in _live(pd.read_parquet(views)):
        images = [np.asarray(Image.open(views_dir / row["files"][i]).convert("RGB")) for i in row["selected"]]
        res, rej = _guard("score", score_step, items[row["asset_id"]], images, config, pool)
        base = {"asset_id": row["asset_id"]}
        if rej:
            rows.append({**base, **rej})
            continue
        s, top = res
        rows.append({**base, "fused": _vec(s.fused), "raw_fused": _vec(s.raw_fused), "image": _vec(s.image),
                     "text": _vec(s.text), "image_embedding": _vec(s.image_embedding),
                     "image_embedding_dtype": _dtype(s.image_embedding), "text_embedding": _vec(s.text_embedding),
                     "text_embedding_dtype": _dtype(s.text_embedding), "top_index": [int(i) for i, _ in top],
                     "top_score": [float(x) for _, x in top], "scorer": config.scoring.scorer_name})
    _write(rows, scores)
    return sum(not _rejected(r) for r in rows)


def _arr(v: Any, dtype: str | None = None) -> np.ndarray | None:
    """A parquet list back as an array (None stays None)."""
    return None if v is None else np.asarray(v, dtype=dtype or np.float64)


def curate(manifest: Path, normalised_dir: Path, views: Path, views_dir: Path, scores: Path, config: IngestConfig,
           catalog_path: Path) -> tuple[int, int]:
    """Curate every scored asset into a fresh catalog, record every rejection, finalize; returns (written, rejected)."""
    from catalogs.records import RejectionRecord
    from catalogs.writer import CatalogWriter, asset_root
    from retrieval.finalize import finalize
    from retrieval.ingest import _write_result, record_pool

    catalog_path = Path(catalog_path)
    if catalog_path.exists() or asset_root(catalog_path).exists():
        raise FileExistsError(f"curate builds a fresh catalog: remove {catalog_path} and {asset_root(catalog_path)}")
    tables = [pd.read_parquet(p) for p in (manifest, views, scores)]
    by_stage = [{r["asset_id"]: r for r in t.to_dict("records")} for t in tables[1:]]
    pool, written, rejected = stage_pool(), 0, 0
    with CatalogWriter(catalog_path) as writer:
        record_pool(writer, pool, config)
        for row in tables[0].to_dict("records"):
            item, h, aid = _item(row), row["content_hash"], row["asset_id"]
            rej = next((r for r in (row, *(t.get(aid) for t in by_stage)) if _rejected(r)), None)
            if rej is None:
                res = _curate_one(item, h, row, by_stage[0][aid], by_stage[1][aid], normalised_dir, views_dir, config,
                                  pool, catalog_path)
                rej = res if isinstance(res, dict) else None
            if rej is not None:
                # Same detail as ingest's rejections: the content hash lets a later ingest skip the same bytes.
                # No config_hash: this stage saw only its own params sections, so a later ingest re-checks them.
                rec = RejectionRecord(item.source, item.source_id, rej["stage"], rej["reason"],
                                      f"{rej['detail']} [sha256:{h[:16]}]")
                res = ItemResult(item.source, item.source_id, h, rejection=rec)
            with writer.transaction():
                _write_result(writer, res, config, catalog_path)
            written, rejected = written + (rej is None), rejected + (rej is not None)
        finalize(writer, config)
    return written, rejected


def _curate_one(item: SourceItem, h: str, row: dict, view_row: dict, score_row: dict, normalised_dir: Path,
                views_dir: Path, config: IngestConfig, pool: DescriptionPool,
                catalog_path: Path) -> ItemResult | dict[str, str]:
    """Copy one asset's views into the catalog and curate it; returns its result or its rejection columns."""
    from catalogs.writer import asset_root

    out = asset_dir_for(item, asset_root(catalog_path))
    src = asset_dir_for(item, views_dir)
    shutil.copytree(src, out, dirs_exist_ok=True)  # views/ and contact_sheet.png, where ingest puts them
    canon = _load_canon(asset_dir_for(item, normalised_dir), row["up_axis"], json.loads(row["params"]))
    n = len(view_row["files"])
    rendered = Rendered([], list(view_row["azimuths"]), list(view_row["elevations"]),
                        [int(i) for i in view_row["selected"]], list(view_row["info"]),
                        [out / Path(f).relative_to(src.relative_to(views_dir)) for f in view_row["files"]])
    views = view_records(asset_id_for(item), rendered,
                         [rendered.files[i].relative_to(catalog_path.parent).as_posix() for i in range(n)])
    s = score_row
    scores = AssetScores(_arr(s["fused"]), _arr(s["image"]), _arr(s["text"]),
                         _arr(s["image_embedding"], s["image_embedding_dtype"]),
                         _arr(s["text_embedding"], s["text_embedding_dtype"]), raw_fused=_arr(s["raw_fused"]))
    top = [(int(i), float(x)) for i, x in zip(s["top_index"], s["top_score"])]
    res, rej = _guard("curate", curate_step, item, h, canon, scores, top, rendered.selected, config, pool,
                      out, catalog_path.parent)
    if rej:
        return rej
    asset, matches = res
    return ItemResult(item.source, item.source_id, h, asset, views, matches, scores.image_embedding,
                      scores.text_embedding)


def dump_catalog(catalog_path: Path, out_dir: Path) -> list[str]:
    """Write every table of a catalog as `out_dir/<table>.parquet`, rows sorted: the catalog's bytes-stable record.

    A DuckDB file is not byte-reproducible (each file gets a random identifier, and block contents vary), so DVC
    tracks this dump instead of the .duckdb: equal catalogs give equal dumps. Returns the table names.
    """
    import duckdb

    out_dir = Path(out_dir)
    if out_dir.exists():
        shutil.rmtree(out_dir)
    out_dir.mkdir(parents=True)
    con = duckdb.connect(str(catalog_path), read_only=True)
    try:
        names = sorted(r[0] for r in con.execute("SELECT table_name FROM information_schema.tables").fetchall())
        for name in names:
            write_parquet(con.sql(f'SELECT * FROM "{name}" ORDER BY ALL').to_arrow_table(),
                          out_dir / f"{name}.parquet")
    finally:
        con.close()
    return names


def main(argv: list[str] | None = None) -> None:
    """`python -m retrieval.stages <stage> --params retrieval/params.yaml [--root outputs/retrieval]`."""
    import yaml
    from rich.console import Console

    from retrieval.executors import die_with_parent

    die_with_parent(os.getppid())  # dvc killed (even by SIGKILL): the stage ends too
    quiet_third_party()
    from curbside.quiet import import_pybullet

    import_pybullet()  # render and curate use pybullet: import it without its build-time banner
    ap = argparse.ArgumentParser(prog="python -m retrieval.stages", description=__doc__.splitlines()[0])
    ap.add_argument("stage", choices=list(STAGE_PARAMS))
    ap.add_argument("--params", type=Path, default=Path("retrieval/params.yaml"))
    ap.add_argument("--root", type=Path, default=Path("outputs/retrieval"), help="folder of the stages' files")
    a = ap.parse_args(argv)
    params = yaml.safe_load(a.params.read_text()) or {}
    config, r = config_for(params, a.stage), a.root
    norm, man, vdir, vt, sc = r / "normalised", r / "manifest.parquet", r / "views", r / "views.parquet", r / "scores.parquet"
    if a.stage == "normalise":
        from retrieval.sources import open_source

        src_p = dict(params.get("source") or {})
        name, limit = src_p.pop("name", "procedural"), src_p.pop("limit", None)
        if name == "procedural":  # generated meshes live with the stage's outputs, so DVC tracks them
            src_p["work_dir"] = norm / "source"
        summary = f"{normalise(open_source(name, **src_p), config, norm, man, limit)} assets normalised -> {norm}"
    elif a.stage == "render":
        summary = f"{render(man, norm, config, vdir, vt)} assets rendered -> {vdir}"
    elif a.stage == "score":
        summary = f"{score(man, vt, vdir, config, sc)} assets scored -> {sc}"
    else:
        catalog = r / "catalog.duckdb"
        # DVC tracks catalog_tables/ (below) and catalog_assets/, not the .duckdb: this stage's previous catalog
        # is its own by-product, so it is replaced here as DVC replaces the tracked outputs.
        for stale in (catalog, catalog.with_name(catalog.name + ".wal")):
            stale.unlink(missing_ok=True)
        written, rejected = curate(man, norm, vt, vdir, sc, config, catalog)
        tables = dump_catalog(catalog, r / "catalog_tables")
        summary = (f"{written} assets written, {rejected} rejected -> {catalog} "
                   f"({len(tables)} tables dumped to {r / 'catalog_tables'})")
    Console(highlight=False, soft_wrap=True).print(f"[bold]{a.stage}[/bold]: {summary}")


if __name__ == "__main__":
    main()
