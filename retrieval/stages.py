"""The asset half as DVC stages: normalise -> render -> score -> curate, each a function over files.

The DVC driver of `retrieval.pipeline`: each stage runs one step (the same code `pipeline.process_item` fuses per
asset) over every item, under the pipeline's guard, and hands its state to the next stage through a folder and a
parquet table, one row per asset; an asset rejected by a stage keeps its row (stage, reason, detail) so `curate`
records it. Run one stage with
`python -m retrieval.stages <stage> --params retrieval/params.yaml [--root outputs/retrieval]`.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
from collections.abc import Iterator
from dataclasses import asdict
from pathlib import Path
from typing import Any, TypedDict

import numpy as np
import pandas as pd

from catalogs.layout import asset_root, retrieved_asset_dir
from kernel.reproducible import quiet_third_party, write_frame
from retrieval.normalize import CanonicalMesh
from retrieval.pipeline import (
    IngestConfig,
    ItemResult,
    Rejection,
    Rendered,
    asset_id,
    config_from_dict,
    curate_step,
    guard,
    normalise_step,
    prefiltered,
    rejected,
    render_step,
    score_step,
    view_records,
)
from retrieval.scoring import AssetScores, DescriptionPool
from retrieval.sources import Source, SourceItem

# The params.yaml sections each stage reads; dvc.yaml lists exactly these (a test checks it).
STAGE_PARAMS: dict[str, tuple[str, ...]] = {
    "normalise": ("source", "normalise"),
    "render": ("render",),
    "score": ("score",),
    "curate": ("score", "curate"),
}
# Which IngestConfig fields each section sets (normalise -> QualityLimits, score -> ScoringConfig).
_SECTION_FIELDS = {
    "render": ("n_views", "n_informative", "image_size", "elevations"),
    "curate": ("collision", "dedupe_threshold", "write_glb"),
}
_REJECT_COLS = tuple(Rejection.__dataclass_fields__)  # stage, reason, detail


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
    from catalogs.categories import NAMES
    from retrieval.scoring import category_pool

    return category_pool(sorted(NAMES))


def _item(row: dict[str, Any]) -> SourceItem:
    """The source item a manifest row was made from."""
    return SourceItem(**json.loads(row["item"]))


def _rejected(row: dict[str, Any] | None) -> bool:
    """Whether a table row records a rejection (a null reason reads back as None or NaN)."""
    return row is not None and isinstance(row.get("reason"), str)


def _rejection(row: dict[str, Any]) -> Rejection:
    """The rejection a table row records."""
    return Rejection(*(row[c] for c in _REJECT_COLS))


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


class _CanonArrays(TypedDict, total=False):
    """The arrays of canonical.npz; uv only when the mesh carries a UV texture."""

    vertices: np.ndarray
    faces: np.ndarray
    face_colors: np.ndarray
    uv: np.ndarray


def _save_canon(canon: CanonicalMesh, out: Path) -> None:
    """Keep the canonical mesh losslessly (the OBJ is rounded and unwelded), for curate to scale and export."""
    arrays: _CanonArrays = {
        "vertices": canon.mesh.vertices,
        "faces": canon.mesh.faces,
        "face_colors": canon.face_colors,
    }
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
    return CanonicalMesh(
        mesh, z["face_colors"], up_axis, Image.open(tex) if tex.exists() else None, z.get("uv"), params
    )


def normalise(source: Source, config: IngestConfig, out_dir: Path, manifest: Path, limit: int | None = None) -> int:
    """Fetch every item and normalise it into `out_dir`; writes the manifest; returns the number kept."""
    rows = []
    for item in source.items(limit):
        row: dict[str, Any] = {
            "asset_id": asset_id(item.source, item.source_id),
            "content_hash": item.content_hash(),
            "item": json.dumps(asdict(item), sort_keys=True),
        }
        rej = prefiltered(item)
        out = retrieved_asset_dir(out_dir, item.source, item.source_id)
        if rej is None:
            norm, rej = guard("normalize", normalise_step, item, config, out)
        if rej is not None:
            rows.append({**row, **asdict(rej)})
            continue
        assert norm is not None  # guard returns a value exactly when it returns no rejection
        _save_canon(norm.canon, out)
        rows.append(
            {
                **row,
                "obj": norm.obj.relative_to(out_dir).as_posix(),
                "up_axis": norm.canon.up_axis,
                "bounds": norm.canon.mesh.bounds.ravel().tolist(),
                "params": json.dumps(norm.canon.params),
            }
        )
    _write(rows, manifest)
    return sum(not _rejected(r) for r in rows)


def render(manifest: Path, normalised_dir: Path, config: IngestConfig, views_dir: Path, views: Path) -> int:
    """Render every normalised asset into `views_dir`; writes the views table; returns the number kept."""
    rows = []
    for row in _live(pd.read_parquet(manifest)):
        item = _item(row)
        out = retrieved_asset_dir(views_dir, item.source, item.source_id)
        bounds = np.asarray(row["bounds"], dtype=np.float64).reshape(2, 3)
        r, rej = guard("render", render_step, item, normalised_dir / row["obj"], bounds, config, out)
        base = {"asset_id": row["asset_id"]}
        if rej:
            rows.append({**base, **asdict(rej)})
            continue
        assert r is not None  # guard returns a value exactly when it returns no rejection
        rows.append(
            {
                **base,
                "files": [f.relative_to(views_dir).as_posix() for f in r.files],
                "azimuths": r.azimuths,
                "elevations": r.elevations,
                "selected": r.selected,
                "info": r.info,
            }
        )
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
        res, rej = guard("score", score_step, items[row["asset_id"]], images, config, pool)
        base = {"asset_id": row["asset_id"]}
        if rej:
            rows.append({**base, **asdict(rej)})
            continue
        assert res is not None  # guard returns a value exactly when it returns no rejection
        s, top = res
        rows.append(
            {
                **base,
                "fused": _vec(s.fused),
                "raw_fused": _vec(s.raw_fused),
                "image": _vec(s.image),
                "text": _vec(s.text),
                "image_embedding": _vec(s.image_embedding),
                "image_embedding_dtype": _dtype(s.image_embedding),
                "text_embedding": _vec(s.text_embedding),
                "text_embedding_dtype": _dtype(s.text_embedding),
                "view_embeddings": None if s.view_embeddings is None else [_vec(v) for v in s.view_embeddings],
                "view_embeddings_dtype": _dtype(s.view_embeddings),
                "top_index": [int(i) for i, _ in top],
                "top_score": [float(x) for _, x in top],
                "scorer": config.scoring.scorer_name,
            }
        )
    _write(rows, scores)
    return sum(not _rejected(r) for r in rows)


def _arr(v: Any, dtype: str | None = None) -> np.ndarray | None:
    """A parquet list back as an array (None stays None)."""
    return None if v is None else np.asarray(v, dtype=dtype or np.float64)


def curate(
    manifest: Path,
    normalised_dir: Path,
    views: Path,
    views_dir: Path,
    scores: Path,
    config: IngestConfig,
    catalog_path: Path,
) -> tuple[int, int]:
    """Curate every scored asset into a fresh catalog, record every rejection, finalize; returns (written, rejected)."""
    from catalogs.writer import CatalogWriter
    from retrieval.finalize import finalize
    from retrieval.pipeline import record_pool, write_result

    catalog_path = Path(catalog_path)
    if catalog_path.exists() or asset_root(catalog_path).exists():
        raise FileExistsError(f"curate builds a fresh catalog: remove {catalog_path} and {asset_root(catalog_path)}")
    tables = [pd.read_parquet(p) for p in (manifest, views, scores)]
    by_stage = [{r["asset_id"]: r for r in t.to_dict("records")} for t in tables[1:]]
    pool, n_written, n_rejected = stage_pool(), 0, 0
    with CatalogWriter(catalog_path) as writer:
        record_pool(writer, pool, config)
        for row in tables[0].to_dict("records"):
            item, h, aid = _item(row), row["content_hash"], row["asset_id"]
            earlier = next((r for r in (row, *(t.get(aid) for t in by_stage)) if _rejected(r)), None)
            if earlier is None:
                res = _curate_one(
                    item,
                    h,
                    row,
                    by_stage[0][aid],
                    by_stage[1][aid],
                    normalised_dir,
                    views_dir,
                    config,
                    pool,
                    catalog_path,
                )
            else:
                # No config_hash: this stage saw only its own params sections, so a later ingest re-checks them.
                res = rejected(item, h, _rejection(earlier), None)
            write_result(writer, res, config, catalog_path)
            n_written, n_rejected = n_written + (res.rejection is None), n_rejected + (res.rejection is not None)
        finalize(writer, config)
    return n_written, n_rejected


def _curate_one(
    item: SourceItem,
    h: str,
    row: dict,
    view_row: dict,
    score_row: dict,
    normalised_dir: Path,
    views_dir: Path,
    config: IngestConfig,
    pool: DescriptionPool,
    catalog_path: Path,
) -> ItemResult:
    """Copy one asset's views into the catalog and curate it; returns its result (or its rejection)."""
    out = retrieved_asset_dir(asset_root(catalog_path), item.source, item.source_id)
    src = retrieved_asset_dir(views_dir, item.source, item.source_id)
    shutil.copytree(src, out, dirs_exist_ok=True)  # views/ and contact_sheet.png, where ingest puts them
    canon = _load_canon(
        retrieved_asset_dir(normalised_dir, item.source, item.source_id), row["up_axis"], json.loads(row["params"])
    )
    rendered = Rendered(
        [],
        list(view_row["azimuths"]),
        list(view_row["elevations"]),
        [int(i) for i in view_row["selected"]],
        list(view_row["info"]),
        [out / Path(f).relative_to(src.relative_to(views_dir)) for f in view_row["files"]],
    )
    views = view_records(asset_id(item.source, item.source_id), rendered, catalog_path.parent)
    s = score_row
    fused = _arr(s["fused"])
    assert fused is not None  # the score stage writes fused scores for every asset it kept
    scores = AssetScores(
        fused,
        _arr(s["image"]),
        _arr(s["text"]),
        _arr(s["image_embedding"], s["image_embedding_dtype"]),
        _arr(s["text_embedding"], s["text_embedding_dtype"]),
        raw_fused=_arr(s["raw_fused"]),
        view_embeddings=None
        if s.get("view_embeddings") is None
        else np.stack([np.asarray(v) for v in s["view_embeddings"]]).astype(s["view_embeddings_dtype"]),
    )
    top = [(int(i), float(x)) for i, x in zip(s["top_index"], s["top_score"])]
    res, rej = guard(
        "curate", curate_step, item, h, canon, scores, top, rendered.selected, config, pool, out, catalog_path.parent
    )
    if rej is not None:
        return rejected(item, h, rej, None)
    assert res is not None  # guard returns a value exactly when it returns no rejection
    asset, matches = res
    return ItemResult(
        item.source,
        item.source_id,
        h,
        asset,
        views,
        matches,
        scores.image_embedding,
        scores.text_embedding,
        scores.view_embeddings,
    )


def main(argv: list[str] | None = None) -> None:
    """`python -m retrieval.stages <stage> --params retrieval/params.yaml [--root outputs/retrieval]`."""
    import yaml
    from rich.console import Console

    from kernel.executors import die_with_parent

    die_with_parent(os.getppid())  # dvc killed (even by SIGKILL): the stage ends too
    quiet_third_party()
    from kernel.quiet import import_pybullet

    import_pybullet()  # render and curate use pybullet: import it without its build-time banner
    ap = argparse.ArgumentParser(prog="python -m retrieval.stages", description=__doc__.splitlines()[0])
    ap.add_argument("stage", choices=list(STAGE_PARAMS))
    ap.add_argument("--params", type=Path, default=Path("retrieval/params.yaml"))
    ap.add_argument("--root", type=Path, default=Path("outputs/retrieval"), help="folder of the stages' files")
    a = ap.parse_args(argv)
    params = yaml.safe_load(a.params.read_text()) or {}
    config, r = config_for(params, a.stage), a.root
    norm, man, vdir, vt, sc = (
        r / "normalised",
        r / "manifest.parquet",
        r / "views",
        r / "views.parquet",
        r / "scores.parquet",
    )
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
        from catalogs.inspect import dump_catalog

        tables = dump_catalog(catalog, r / "catalog_tables")
        summary = (
            f"{written} assets written, {rejected} rejected -> {catalog} "
            f"({len(tables)} tables dumped to {r / 'catalog_tables'})"
        )
    Console(highlight=False, soft_wrap=True).print(f"[bold]{a.stage}[/bold]: {summary}")


if __name__ == "__main__":
    main()
