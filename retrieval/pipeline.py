"""The asset half's per-asset pipeline: normalise -> render -> score -> curate, one guard, one item result.

Two drivers run it: `retrieval.ingest` fuses the four steps per asset (`process_item`, any executor, resumable)
and `retrieval.stages` runs one step per DVC stage over every asset, handing state over through files. Every
step raises `AssetRejected` for a bad asset; `guard` is the one place that turns a failed step into a
`Rejection`, `rejected` the one place that turns a rejection into the row the catalog records, and
`write_result` writes an `ItemResult` through the catalog writer.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from catalogs.layout import IMAGE_EMBEDDING_FILE, asset_root, retrieved_asset_dir, stored_path
from catalogs.records import AssetRecord, DescriptionRecord, MatchRecord, RejectionRecord, ViewRecord
from catalogs.schema import DESCRIPTION_KIND
from kernel.config import ConfigError
from retrieval.defaults import DEFAULT_N_VIEWS, MAX_VIEWS
from retrieval.normalize import AssetRejected, CanonicalMesh, QualityLimits
from retrieval.scoring import AssetScores, DescriptionPool, ScoringConfig
from retrieval.sources import SourceItem

if TYPE_CHECKING:  # the writer (pyarrow) loads only in the process that writes, not in every worker
    from catalogs.writer import CatalogWriter

T = TypeVar("T")


@dataclass(frozen=True)
class IngestConfig:
    """Parameters of the per-asset steps and their drivers (defaults mirror retrieval/params.yaml)."""

    n_views: int = DEFAULT_N_VIEWS
    n_informative: int = 3
    image_size: int = 160
    elevations: tuple[float, float] = (15.0, 40.0)
    scoring: ScoringConfig = ScoringConfig()
    limits: QualityLimits = QualityLimits()
    collision: str = "convex"
    dedupe_threshold: float = 0.995
    max_rejections: int | None = None
    write_glb: bool = True

    def __post_init__(self) -> None:
        # Checked here, once, so a bad value stops the run before any asset: inside a step it would become a
        # per-asset rejection of every asset, remembered by content hash (e.g. --views 0).
        if not (isinstance(self.n_views, int) and 1 <= self.n_views <= MAX_VIEWS):
            raise ConfigError(f"n_views must be an integer in 1..{MAX_VIEWS}, got {self.n_views!r}; e.g. --views 8")
        if not (isinstance(self.n_informative, int) and self.n_informative >= 1):
            raise ConfigError(f"n_informative must be an integer >= 1, got {self.n_informative!r}")
        if not (isinstance(self.image_size, int) and self.image_size >= 16):
            raise ConfigError(f"image_size must be an integer >= 16 pixels, got {self.image_size!r}")
        if len(self.elevations) != 2:
            raise ConfigError(f"elevations must be two angles in degrees, got {self.elevations!r}")
        if self.max_rejections is not None and self.max_rejections < 0:
            raise ConfigError(f"max_rejections must be >= 0 or None, got {self.max_rejections!r}")


def config_hash(config: IngestConfig) -> str:
    """Short hash of everything in the configuration that can change an asset's verdict (not max_rejections)."""
    d = dataclasses.asdict(config)
    d.pop("max_rejections", None)  # a run-level stop rule: it never decides one asset's fate
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:16]


def config_from_dict(d: dict[str, Any]) -> IngestConfig:
    """Build an IngestConfig from a plain (e.g. params.yaml) dict, strict about keys."""
    from kernel.config import merge_strict

    base = dataclasses.asdict(IngestConfig())
    merged = merge_strict(base, d, name="ingest config")
    merged["scoring"] = ScoringConfig(**merged["scoring"])
    merged["limits"] = QualityLimits(**merged["limits"])
    merged["elevations"] = tuple(merged["elevations"])
    return IngestConfig(**merged)


def asset_id(source: str, source_id: str) -> str:
    """Stable catalog id of an item: source and source id."""
    return f"{source}:{source_id}"


@dataclass(frozen=True)
class Rejection:
    """Why a step refused an asset: the stage, a short reason code and what was found."""

    stage: str
    reason: str
    detail: str


@dataclass
class ItemResult:
    """One item's outcome: the rows of a finished asset, or its rejection."""

    source: str
    source_id: str
    content_hash: str
    asset: AssetRecord | None = None
    views: list[ViewRecord] = field(default_factory=list)
    matches: list[MatchRecord] = field(default_factory=list)
    image_embedding: np.ndarray | None = None
    text_embedding: np.ndarray | None = None
    view_embeddings: np.ndarray | None = (
        None  # the scored (informative) views', in asset.params informative_views order
    )
    rejection: RejectionRecord | None = None
    seconds: dict[str, float] = field(default_factory=dict)


def guard(stage: str, fn: Callable[..., T], *args: Any) -> tuple[T | None, Rejection | None]:
    """Run one step; a bad asset becomes (None, its Rejection) instead of stopping the run."""
    try:
        return fn(*args), None
    except AssetRejected as rej:
        return None, Rejection(stage, rej.reason, rej.detail)
    except ConfigError:
        raise  # a bad configuration is wrong for every asset: stop the run, never blame (and skip) the asset
    except Exception as exc:  # noqa: BLE001 - one broken asset must never stop the run; the reason is kept
        tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
        return None, Rejection(stage, "error", tb[:400])


def prefiltered(item: SourceItem) -> Rejection | None:
    """The rejection a source's prefilter (licence, annotated size, download) attached to the item, if any."""
    if "rejected" not in item.metadata:
        return None
    reason, detail = item.metadata["rejected"]
    return Rejection("fetch", reason, detail)


def rejected(item: SourceItem, content_hash: str, rejection: Rejection, cfg_hash: str | None) -> ItemResult:
    """The result of a refused item: its rejection row, tagged with the content and configuration hashes."""
    # The content hash in the detail lets a re-run skip the same bytes yet retry a fixed file; the config hash
    # makes a run under another configuration retry it too (None: a DVC stage saw only part of the config).
    rec = RejectionRecord(
        item.source,
        item.source_id,
        rejection.stage,
        rejection.reason,
        f"{rejection.detail} [sha256:{content_hash[:16]}]",
        cfg_hash,
    )
    return ItemResult(item.source, item.source_id, content_hash, rejection=rec)


@dataclass
class Normalised:
    """Output of the normalise step: the canonical mesh and its (unscaled) OBJ for rendering."""

    canon: CanonicalMesh
    obj: Path


@dataclass
class Rendered:
    """Output of the render step: all views, the informative ones and the files they were saved to."""

    images: list[np.ndarray]
    azimuths: list[float]
    elevations: list[float]
    selected: list[int]
    info: list[float]
    files: list[Path]


def normalise_step(item: SourceItem, config: IngestConfig, out: Path) -> Normalised:
    """Load, filter and canonicalise the item's mesh; write its OBJ (+ MTL, texture) into `out`."""
    from retrieval.normalize import export_obj, load_canonical

    canon = load_canonical(item.path, up_axis=item.up_axis, limits=config.limits)
    obj, _, _ = export_obj(canon, out, "mesh")
    return Normalised(canon, obj)


def render_step(item: SourceItem, obj: Path, bounds: np.ndarray, config: IngestConfig, out: Path) -> Rendered:
    """Render the views into `out/views`, pick the informative ones and write `out/contact_sheet.png`."""
    from PIL import Image

    from retrieval.render import contact_sheet, render_obj, select_informative, view_specs

    specs = view_specs(config.n_views, config.elevations)
    images = render_obj(obj, specs, size=config.image_size, bounds=bounds)
    selected, info = select_informative(images, config.n_informative)
    if max(info) <= 0.0:
        raise AssetRejected("degenerate", "every rendered view is empty")
    (out / "views").mkdir(parents=True, exist_ok=True)
    files = []
    for i, im in enumerate(images):
        path = out / "views" / f"view_{i:02d}.png"
        Image.fromarray(im).save(path, compress_level=1)  # fast zlib: 20 views an asset
        files.append(path)
    contact_sheet(images, selected, title=f"{item.source}:{item.source_id}", scores=info).save(
        out / "contact_sheet.png", compress_level=1
    )
    return Rendered(images, [s.azimuth for s in specs], [s.elevation for s in specs], selected, info, files)


def view_records(aid: str, rendered: Rendered, catalog_dir: str | Path) -> list[ViewRecord]:
    """Catalog rows of the rendered views, whose files lie under `catalog_dir`."""
    return [
        ViewRecord(
            aid,
            i,
            rendered.azimuths[i],
            rendered.elevations[i],
            stored_path(f, catalog_dir),
            i in rendered.selected,
            round(rendered.info[i], 6),
        )
        for i, f in enumerate(rendered.files)
    ]


def score_step(
    item: SourceItem, images: list[np.ndarray], config: IngestConfig, pool: DescriptionPool
) -> tuple[AssetScores, list[tuple[int, float]]]:
    """Score the informative views and the metadata text against the pool; returns scores and the top matches."""
    from retrieval.scoring import cached_scorer

    scorer = cached_scorer(config.scoring, pool)
    scores = scorer.score(images, item.metadata_text)
    return scores, scorer.top_matches(scores)


def curate_step(
    item: SourceItem,
    content_hash: str,
    canon: CanonicalMesh,
    scores: AssetScores,
    top: list[tuple[int, float]],
    selected: list[int],
    config: IngestConfig,
    pool: DescriptionPool,
    out: Path,
    catalog_dir: str | Path,
) -> tuple[AssetRecord, list[MatchRecord]]:
    """Pick the category, normalise the size, export OBJ/collision/GLB into `out`; returns the asset and matches."""
    from catalogs.categories import CATEGORIES
    from retrieval.curation import OPEN_OBJECT_CLASS, normalize_open_size, normalize_size
    from retrieval.normalize import export_collision, export_glb, export_obj, scale_mesh

    category = item.category or (pool.categories[top[0][0]] if top else None)
    open_vocabulary = category is None and item.category is None and bool(top)
    if open_vocabulary:
        # The best match is an open-vocabulary description (category None): the asset is kept under its label.
        category = open_label(pool.texts[top[0][0]])
    if category is None:
        best = int(np.argmax(scores.fused))
        raw = scores.raw_fused[best] if scores.raw_fused is not None else scores.fused[best]
        raise AssetRejected(
            "no_match",
            f"best {pool.ids[best]}: calibrated {scores.fused[best]:.3f}, raw "
            f"{raw:.3f} (threshold {config.scoring.threshold}, min_lift "
            f"{config.scoring.min_lift})",
        )
    prior = CATEGORIES.get(category)
    if prior is None and not open_vocabulary:
        raise AssetRejected(
            "unknown_category",
            f"{category!r} is not in catalogs/categories.csv; give the source item one of: {', '.join(CATEGORIES)}",
        )
    scale, unit = normalize_size(canon.extents, category) if prior else normalize_open_size(canon.extents)
    final = scale_mesh(canon, scale)
    obj, _, _ = export_obj(final, out, "mesh")
    coll = export_collision(final, out) if config.collision == "convex" else None
    glb = export_glb(final, out) if config.write_glb else None
    depth, width, height = (float(x) for x in final.extents)
    aid = asset_id(item.source, item.source_id)

    def rel(p: Path | None) -> str | None:
        return stored_path(p, catalog_dir) if p else None

    asset = AssetRecord(
        asset_id=aid,
        source=item.source,
        source_id=item.source_id,
        category=category,
        object_class=prior.object_class if prior else OPEN_OBJECT_CLASS,
        zones=list(prior.zones) if prior else [],
        depth=round(depth, 6),
        width=round(width, 6),
        height=round(height, 6),
        description=item.description or (f"{category.replace('_', ' ')}: {item.name}" if item.name else category),
        synonyms=list(item.tags),
        license=item.license,
        attribution=item.attribution,
        mesh_path=rel(obj),
        glb_path=rel(glb),
        collision=config.collision,
        collision_path=rel(coll),
        face_count=int(final.mesh.faces.shape[0]),
        watertight=bool(final.mesh.is_watertight),
        content_hash=content_hash,
        params={
            **canon.params,
            "scale": round(scale, 9),
            "unit_guess": unit,
            "name": item.name,
            "scorer": config.scoring.scorer_name,
            "informative_views": list(selected),
            **({"open_vocabulary": True} if open_vocabulary else {}),
            **{k: v for k, v in item.metadata.items() if k != "companion_files"},
        },
    )
    matches = [
        MatchRecord(
            aid,
            pool.ids[i],
            round(s, 6),
            config.scoring.scorer_name,
            None if scores.image is None else round(float(scores.image[i]), 6),
            None if scores.text is None else round(float(scores.text[i]), 6),
            rank,
        )
        for rank, (i, s) in enumerate(top, start=1)
    ]
    return asset, matches


def open_label(text: str) -> str:
    """The catalog category of an open-vocabulary asset: its description's words, article dropped, snake_case."""
    import re

    words = re.sub(r"^(a|an|the)\s+", "", text.strip().lower())
    return re.sub(r"[^a-z0-9]+", "_", words).strip("_")[:60] or "object"


def process_item(
    item: SourceItem, config: IngestConfig, pool: DescriptionPool, root: str, catalog_dir: str
) -> ItemResult:
    """Run the four steps on one item, its files under the asset root `root`; never raises for a bad asset."""
    h = item.content_hash()

    def refuse(rej: Rejection) -> ItemResult:
        return rejected(item, h, rej, config_hash(config))

    rej = prefiltered(item)
    if rej is not None:
        return refuse(rej)
    aid, out = asset_id(item.source, item.source_id), retrieved_asset_dir(root, item.source, item.source_id)
    times: dict[str, float] = {}

    def timed(stage: str, fn: Callable[..., T], *args: Any) -> tuple[T | None, Rejection | None]:
        t0 = time.perf_counter()
        try:
            return guard(stage, fn, *args)
        finally:
            times[stage] = time.perf_counter() - t0

    def render(norm: Normalised) -> tuple[Rendered, list[ViewRecord]]:
        r = render_step(item, norm.obj, norm.canon.mesh.bounds, config, out)
        return r, view_records(aid, r, catalog_dir)

    norm, rej = timed("normalize", normalise_step, item, config, out)
    if rej is not None:
        return refuse(rej)
    assert norm is not None  # guard returns a value exactly when it returns no rejection
    rendered_views, rej = timed("render", render, norm)
    if rej is not None:
        return refuse(rej)
    assert rendered_views is not None
    rendered, views = rendered_views
    scored, rej = timed("score", score_step, item, [rendered.images[i] for i in rendered.selected], config, pool)
    if rej is not None:
        return refuse(rej)
    assert scored is not None
    scores, top = scored
    curated, rej = timed(
        "curate", curate_step, item, h, norm.canon, scores, top, rendered.selected, config, pool, out, catalog_dir
    )
    if rej is not None:
        return refuse(rej)
    assert curated is not None
    asset, matches = curated
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
        seconds=times,
    )


def record_pool(writer: CatalogWriter, pool: DescriptionPool, config: IngestConfig) -> None:
    """Store the category prompts (and their embeddings) when they are the pool, so matches reference real rows."""
    from retrieval.scoring import cached_scorer

    if pool.origin != "category_prompts":
        return
    scorer = cached_scorer(config.scoring, pool)
    writer.upsert_descriptions(
        DescriptionRecord(i, t, c, sources=["category_prompt"])
        for i, t, c in zip(pool.ids, pool.texts, pool.categories)
    )
    if scorer.pool_text.shape[1] == writer.embedding_dim:
        writer.upsert_embeddings(DESCRIPTION_KIND, list(pool.ids), scorer.pool_text)


def write_result(writer: CatalogWriter, res: ItemResult, config: IngestConfig, catalog_path: Path) -> None:
    """Write one item's result, whole or not at all: the finished asset's rows, or its rejection."""
    aid = asset_id(res.source, res.source_id)
    if res.rejection is not None:
        writer.reject_assets([(aid, res.rejection)])
        return
    assert res.asset is not None  # an ItemResult holds either its rejection or its asset
    image = res.image_embedding
    if image is not None and image.shape[0] != writer.embedding_dim:
        # CLIP's space has another width than the catalog's FLOAT[n] column: kept next to the asset instead.
        folder = retrieved_asset_dir(asset_root(catalog_path), res.source, res.source_id)
        np.save(folder / IMAGE_EMBEDDING_FILE, image)
        image = None
    per_view = res.view_embeddings
    if per_view is not None and per_view.shape[-1] != writer.embedding_dim:
        per_view = None  # another width than the catalog's (CLIP, BLIP): the mean above is kept beside the asset
    writer.replace_asset(
        res.asset,
        res.views,
        res.matches,
        text_embedding=res.text_embedding,
        image_embedding=image,
        image_model=config.scoring.scorer_name.split(":")[0],
        view_embeddings=per_view,
        view_ids=res.asset.params.get("informative_views", []),
    )
