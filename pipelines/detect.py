"""Stage `detect`: street images + manifest -> open-vocabulary boxes -> NMS -> boxes standing on the sidewalk."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pipelines.boxes import load_sidewalk_polygons, mask_overlap, nms, polygon_overlap
from pipelines.common import PipelineError, load_params, progress, stage_cli, write_metrics, write_table
from pipelines.countries import check_country

MANIFEST_COLUMNS = ("path", "country", "lat", "lon")
DETECTION_COLUMNS = [
    "image",
    "country",
    "lat",
    "lon",
    "img_width",
    "img_height",
    "label",
    "category",
    "score",
    "x0",
    "y0",
    "x1",
    "y1",
    "sidewalk_overlap",
    "sidewalk_source",
]
FILTERS = ("auto", "annotations", "model", "none")


def read_manifest(manifest: str | Path, images_dir: str | Path | None = None):  # noqa: ANN201 - pandas.DataFrame
    """Read and validate an image manifest (path, country, lat, lon[, annotation]); paths resolved to images_dir."""
    import pandas as pd

    m = Path(manifest)
    if not m.exists():
        raise PipelineError(f"image manifest {m} not found; set detect.manifest to a CSV (path, country, lat, lon)")
    df = pd.read_csv(m, dtype={"path": str, "country": str, "annotation": str}, keep_default_na=False)
    missing = [c for c in MANIFEST_COLUMNS if c not in df.columns]
    if missing:
        raise PipelineError(
            f"manifest {m} lacks column(s) {', '.join(missing)}; required: {', '.join(MANIFEST_COLUMNS)}"
        )
    df["country"] = [check_country(c, where=f"manifest {m} row {i + 2}") for i, c in enumerate(df["country"])]
    for col, lim in (("lat", 90.0), ("lon", 180.0)):
        vals = pd.to_numeric(df[col], errors="coerce")
        bad = df.index[vals.isna() | (vals.abs() > lim)].tolist()
        if bad:
            raise PipelineError(
                f"manifest {m}: rows {[i + 2 for i in bad]} have an invalid {col} (need a number in ±{lim})"
            )
        df[col] = vals.astype(float)
    base = Path(images_dir) if images_dir else m.parent
    df["file"] = [str(base / p) for p in df["path"]]
    if "annotation" not in df.columns:
        df["annotation"] = ""
    df["annotation"] = [str(base / a) if a else "" for a in df["annotation"]]
    return df


def load_prompts(closed_set_path: str | Path, sources: list[str]) -> tuple[list[str], list[str]]:
    """Detector prompts and their categories from the closed-set table (deduplicated, sorted)."""
    import pandas as pd

    cs = pd.read_parquet(closed_set_path)
    cs = cs[cs["source"].isin(sources)].drop_duplicates("prompt").sort_values("prompt")
    if cs.empty:
        raise PipelineError(
            f"no closed-set prompts for sources {sources}; valid sources: {sorted(set(pd.read_parquet(closed_set_path)['source']))}"
        )
    return cs["prompt"].tolist(), cs["category"].tolist()


def detect_images(
    manifest: Any,
    prompts: list[str],
    categories: list[str],
    detector: Any,
    *,
    score_threshold: float,
    nms_iou: float,
    sidewalk_filter: str,
    segmenter: Any = None,
    sidewalk_labels: Sequence[str] = (),
    min_overlap: float = 0.3,
    bottom_fraction: float = 0.25,
) -> tuple[Any, Any, dict[str, int]]:
    """Pure function of the stage: (detections kept, images skipped with the reason, counts)."""
    import pandas as pd
    from PIL import Image, UnidentifiedImageError

    rows, skipped = [], []
    counts = {
        "images": len(manifest),
        "images_unreadable": 0,
        "boxes_raw": 0,
        "boxes_after_nms": 0,
        "boxes_off_sidewalk": 0,
        "boxes_unfiltered": 0,
        "detections": 0,
    }
    with progress() as bar:
        task = bar.add_task("detect", total=len(manifest))
        for r in manifest.itertuples():
            bar.advance(task)
            try:
                with Image.open(r.file) as im:
                    image = im.convert("RGB")
            except (OSError, UnidentifiedImageError) as exc:
                counts["images_unreadable"] += 1
                skipped.append({"image": r.path, "reason": f"unreadable: {exc}"})
                continue
            boxes, scores, labels = detector.detect(image, prompts, score_threshold)
            counts["boxes_raw"] += len(boxes)
            keep = nms(boxes, scores, nms_iou)
            boxes, scores, labels = boxes[keep], scores[keep], labels[keep]
            counts["boxes_after_nms"] += len(boxes)
            source = sidewalk_filter
            if source == "auto":
                source = "annotations" if r.annotation else ("model" if segmenter is not None else "none")
            if source == "annotations":
                if not r.annotation:
                    raise PipelineError(
                        f"image {r.path} has no annotation but detect.sidewalk_filter=annotations; "
                        f"add an annotation column to the manifest or use sidewalk_filter: auto"
                    )
                overlap = polygon_overlap(
                    boxes, load_sidewalk_polygons(r.annotation, list(sidewalk_labels)), bottom_fraction
                )
            elif source == "model":
                if segmenter is None:
                    raise PipelineError("detect.sidewalk_filter=model needs detect.segmentation_model (a local path)")
                overlap = mask_overlap(boxes, segmenter.mask(image), bottom_fraction)
            else:
                overlap = np.full(len(boxes), np.nan)
                counts["boxes_unfiltered"] += len(boxes)
            on = np.isnan(overlap) | (overlap >= min_overlap)
            counts["boxes_off_sidewalk"] += int((~on).sum())
            for b, s, lab, ov in zip(boxes[on], scores[on], labels[on], overlap[on], strict=True):
                rows.append(
                    {
                        "image": r.path,
                        "country": r.country,
                        "lat": r.lat,
                        "lon": r.lon,
                        "img_width": image.size[0],
                        "img_height": image.size[1],
                        "label": prompts[lab],
                        "category": categories[lab],
                        "score": float(s),
                        "x0": float(b[0]),
                        "y0": float(b[1]),
                        "x1": float(b[2]),
                        "y1": float(b[3]),
                        "sidewalk_overlap": float(ov),
                        "sidewalk_source": source,
                    }
                )
    counts["detections"] = len(rows)
    return (pd.DataFrame(rows, columns=DETECTION_COLUMNS), pd.DataFrame(skipped, columns=["image", "reason"]), counts)


def run(params_path: str | None = None) -> dict[str, int]:
    """Stage entry: write data/detect/{detections,skipped}.parquet and metrics.json (zero images by default)."""
    import pandas as pd

    from pipelines.detector import SidewalkSegmenter, ZeroShotDetector

    p = load_params(params_path, "detect")
    if p["sidewalk_filter"] not in FILTERS:
        raise PipelineError(f"unknown detect.sidewalk_filter {p['sidewalk_filter']!r}; valid: {', '.join(FILTERS)}")
    out = Path(p["out_dir"])
    if not p["manifest"]:
        # No image set configured: record that nothing was seen, never invent detections.
        dets, skipped = pd.DataFrame(columns=DETECTION_COLUMNS), pd.DataFrame(columns=["image", "reason"])
        counts = {
            "images": 0,
            "images_unreadable": 0,
            "boxes_raw": 0,
            "boxes_after_nms": 0,
            "boxes_off_sidewalk": 0,
            "boxes_unfiltered": 0,
            "detections": 0,
        }
    else:
        manifest = read_manifest(p["manifest"], p["images_dir"] or None)
        prompts, cats = load_prompts(p["closed_set"], list(p["prompt_sources"]))
        detector = ZeroShotDetector(p["model"])
        segmenter = (
            SidewalkSegmenter(p["segmentation_model"], list(p["sidewalk_labels"])) if p["segmentation_model"] else None
        )
        dets, skipped, counts = detect_images(
            manifest,
            prompts,
            cats,
            detector,
            score_threshold=float(p["score_threshold"]),
            nms_iou=float(p["nms_iou"]),
            sidewalk_filter=p["sidewalk_filter"],
            segmenter=segmenter,
            sidewalk_labels=list(p["sidewalk_labels"]),
            min_overlap=float(p["min_overlap"]),
            bottom_fraction=float(p["bottom_fraction"]),
        )
    dets = dets.astype({"score": float, "x0": float, "y0": float, "x1": float, "y1": float})
    write_table(dets, out / "detections.parquet")
    write_table(skipped.astype(str), out / "skipped.parquet")
    write_metrics(out / "metrics.json", counts)
    return counts


if __name__ == "__main__":
    stage_cli("detect", run)
