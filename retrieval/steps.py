"""The per-asset steps of the asset half: normalise -> render -> score -> curate.

One implementation shared by `ingest.process_item` (all four fused per asset, in memory) and the DVC stages of
`retrieval.stages` (one step per stage, state handed over through files). Every step raises `AssetRejected` for a
bad asset; callers turn it into a rejection row.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from catalogs.records import AssetRecord, MatchRecord, ViewRecord
from retrieval.normalize import AssetRejected, CanonicalMesh
from retrieval.scoring import AssetScores, DescriptionPool
from retrieval.sources import SourceItem


def asset_id_for(item: SourceItem) -> str:
    """Stable catalog id of an item: source and source id."""
    return f"{item.source}:{item.source_id}"


def asset_dir_for(item: SourceItem, root: Path) -> Path:
    """Folder of an asset's files under the catalog's asset root."""
    slug = re.sub(r"[^A-Za-z0-9._-]+", "_", item.source_id).strip("_")[:80] or "asset"
    return root / "retrieval" / item.source / slug


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


def normalise_step(item: SourceItem, config, out: Path) -> Normalised:  # noqa: ANN001 - IngestConfig
    """Load, filter and canonicalise the item's mesh; write its OBJ (+ MTL, texture) into `out`."""
    from retrieval.normalize import export_obj, load_canonical

    canon = load_canonical(item.path, up_axis=item.up_axis, limits=config.limits)
    obj, _, _ = export_obj(canon, out, "mesh")
    return Normalised(canon, obj)


def render_step(item: SourceItem, obj: Path, bounds: np.ndarray, config, out: Path) -> Rendered:  # noqa: ANN001
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
        Image.fromarray(im).save(path)
        files.append(path)
    contact_sheet(images, selected, title=f"{item.source}:{item.source_id}").save(out / "contact_sheet.png")
    return Rendered(images, [s.azimuth for s in specs], [s.elevation for s in specs], selected, info, files)


def view_records(aid: str, rendered: Rendered, paths: list[str]) -> list[ViewRecord]:
    """Catalog rows of the rendered views; `paths` are the images' catalog-relative paths."""
    return [ViewRecord(aid, i, rendered.azimuths[i], rendered.elevations[i], paths[i], i in rendered.selected,
                       round(rendered.info[i], 6)) for i in range(len(paths))]


def score_step(item: SourceItem, images: list[np.ndarray], config, pool: DescriptionPool  # noqa: ANN001
               ) -> tuple[AssetScores, list[tuple[int, float]]]:
    """Score the informative views and the metadata text against the pool; returns scores and the top matches."""
    from retrieval.scoring import cached_scorer

    scorer = cached_scorer(config.scoring, pool)
    scores = scorer.score(images, item.metadata_text)
    return scores, scorer.top_matches(scores)


def curate_step(item: SourceItem, content_hash: str, canon: CanonicalMesh, scores: AssetScores,
                top: list[tuple[int, float]], selected: list[int], config, pool: DescriptionPool,  # noqa: ANN001
                out: Path, catalog_dir: str | Path) -> tuple[AssetRecord, list[MatchRecord]]:
    """Pick the category, normalise the size, export OBJ/collision/GLB into `out`; returns the asset and matches."""
    from retrieval.curation import load_size_priors, normalize_size
    from retrieval.normalize import export_collision, export_glb, export_obj, scale_mesh

    priors = load_size_priors()
    category = item.category or next((pool.categories[i] for i, _ in top if pool.categories[i]), None)
    if category is None:
        best = int(np.argmax(scores.fused))
        raw = scores.raw_fused[best] if scores.raw_fused is not None else scores.fused[best]
        raise AssetRejected("no_match", f"best {pool.ids[best]}: calibrated {scores.fused[best]:.3f}, raw "
                                        f"{raw:.3f} (threshold {config.scoring.threshold}, min_lift "
                                        f"{config.scoring.min_lift})")
    scale, unit = normalize_size(canon.extents, category, priors)
    final = scale_mesh(canon, scale)
    obj, _, _ = export_obj(final, out, "mesh")
    coll = export_collision(final, out) if config.collision == "convex" else None
    glb = export_glb(final, out) if config.write_glb else None
    depth, width, height = (float(x) for x in final.extents)
    prior = priors.get(category)
    aid = asset_id_for(item)
    rel = lambda p: p.relative_to(catalog_dir).as_posix() if p else None  # noqa: E731
    asset = AssetRecord(
        asset_id=aid, source=item.source, source_id=item.source_id, category=category,
        object_class=prior.object_class if prior else "clutter",
        zones=list(prior.zones) if prior else ["clear"], depth=round(depth, 6), width=round(width, 6),
        height=round(height, 6),
        description=item.description or (f"{category.replace('_', ' ')}: {item.name}" if item.name else category),
        synonyms=list(item.tags), license=item.license, attribution=item.attribution,
        mesh_path=rel(obj), glb_path=rel(glb), collision=config.collision, collision_path=rel(coll),
        face_count=int(final.mesh.faces.shape[0]), watertight=bool(final.mesh.is_watertight),
        content_hash=content_hash,
        params={**canon.params, "scale": round(scale, 9), "unit_guess": unit, "name": item.name,
                "scorer": config.scoring.scorer_name, "informative_views": list(selected),
                **{k: v for k, v in item.metadata.items() if k != "companion_files"}},
    )
    matches = [MatchRecord(aid, pool.ids[i], round(s, 6), config.scoring.scorer_name,
                           None if scores.image is None else round(float(scores.image[i]), 6),
                           None if scores.text is None else round(float(scores.text[i]), 6), rank)
               for rank, (i, s) in enumerate(top, start=1)]
    return asset, matches
