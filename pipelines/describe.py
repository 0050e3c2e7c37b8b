"""Stage `describe`: one text description per observed object (detections, OSM nodes, closed-set classes)."""

from __future__ import annotations

import colorsys
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from catalogs.categories import category
from pipelines.common import PipelineError, load_params, progress, stage_cli, write_metrics, write_table
from pipelines.signs import SignTable, sign_table

DESCRIPTION_COLUMNS = ["text", "category", "source", "country", "count"]
_MATERIAL_ADJ = {
    "wood": "wooden",
    "metal": "metal",
    "steel": "steel",
    "concrete": "concrete",
    "stone": "stone",
    "plastic": "plastic",
    "granite": "granite",
    "aluminium": "aluminium",
    "brick": "brick",
}


def colour_name(rgb: tuple[float, float, float]) -> str:
    """Basic colour name of an RGB triple (0-255) from hue, saturation and value bands."""
    h, s, v = colorsys.rgb_to_hsv(*(c / 255.0 for c in rgb))
    if v < 0.2:
        return "black"
    if s < 0.15:
        return "white" if v > 0.85 else ("gray" if v > 0.35 else "dark gray")
    deg = h * 360
    if (deg < 45 or deg >= 345) and v < 0.55 and s > 0.3:
        return "brown"
    for limit, name in (
        (15, "red"),
        (45, "orange"),
        (70, "yellow"),
        (165, "green"),
        (200, "teal"),
        (255, "blue"),
        (290, "purple"),
        (345, "pink"),
        (361, "red"),
    ):
        if deg < limit:
            return name
    return "red"


def dominant_colour(pixels: np.ndarray) -> str:
    """Most frequent colour name over the pixels of an (h, w, 3) uint8 crop (inner 60 % to skip background)."""
    h, w = pixels.shape[:2]
    inner = pixels[
        int(h * 0.2) : max(int(h * 0.8), int(h * 0.2) + 1), int(w * 0.2) : max(int(w * 0.8), int(w * 0.2) + 1)
    ]
    flat = inner.reshape(-1, 3)
    # Sub-sample big crops: the mode of a few thousand pixels is stable and fast.
    if len(flat) > 4096:
        flat = flat[:: len(flat) // 4096]
    names = Counter(colour_name(tuple(px)) for px in flat.tolist())
    return sorted(names.items(), key=lambda kv: (-kv[1], kv[0]))[0][0]


def size_word(box_height: float, image_height: float, small_max: float, medium_max: float) -> str:
    """Apparent size from the box height as a fraction of the image height."""
    frac = box_height / max(image_height, 1.0)
    return "small" if frac < small_max else ("medium" if frac < medium_max else "large")


def _article(phrase: str) -> str:
    # "a utility pole", "a unit", "a one-way sign": a leading 'u' read as 'you' or 'o' as 'won' takes "a".
    vowel = phrase[:1].lower() in "aeiou" and not phrase.lower().startswith(("uti", "uni", "use", "one"))
    return ("an " if vowel else "a ") + phrase


def _tag(row: Any, key: str) -> str | None:
    """A tag value, or None when absent (parquet gives None or NaN for missing tags)."""
    v = row.get(key)
    if v is None or (isinstance(v, float) and np.isnan(v)) or str(v).strip() == "":
        return None
    return str(v).split(";")[0].strip()


def osm_description(row: Any, signs: SignTable | None = None) -> str:
    """Text for an OSM object from its category or label and attribute tags (colour, material, backrest...).

    A traffic_sign=<code> tag becomes the sign's name ("a no stopping sign") through the sign table; a code the
    table does not know reads "a traffic sign", never the raw code.
    """
    tag = str(row.get("tag") or "")
    label = _tag(row, "label")
    if tag.startswith("traffic_sign="):
        sign = (signs or sign_table()).describe(tag.split("=", 1)[1])
        words = sign.split(" ", 1)[1]  # without its article: adjectives go in front
    elif label:
        words = label
    elif _tag(row, "category"):
        words = category(row["category"], where="describe").words
    else:
        raise PipelineError(
            f"OSM object {row.get('osm_id')} ({tag}) has neither a category nor a label; "
            f"re-run the osm stage with catalogs/closed_set/osm_tags.csv"
        )
    adj = []
    colour, material = _tag(row, "colour"), _tag(row, "material")
    if colour:
        adj.append(colour.replace("_", " "))
    if material:
        adj.append(_MATERIAL_ADJ.get(material, material))
    leaf_type = _tag(row, "leaf_type")
    if leaf_type in ("broadleaved", "needleleaved"):
        adj.append(leaf_type)
    support = _tag(row, "support") or ""
    if support in ("wall_mounted", "wall", "ceiling", "suspended"):
        adj.append("wall-mounted" if "wall" in support else "suspended")
    text = _article(" ".join([*adj, words]))
    if _tag(row, "backrest") == "yes":
        text += " with a backrest"
    elif _tag(row, "backrest") == "no":
        text += " without a backrest"
    if _tag(row, "genus"):
        text += f" ({_tag(row, 'genus')})"
    return text


def describe_detections(dets: Any, image_files: dict[str, str], *, small_max: float, medium_max: float) -> list[dict]:
    """One description per kept box: '<size> <colour> <label>' from the box's pixels."""
    from PIL import Image

    rows: list[dict] = []
    if dets.empty:
        return rows
    with progress() as bar:
        task = bar.add_task("describe boxes", total=len(dets))
        for image, grp in dets.groupby("image", sort=True):
            file = image_files.get(image)
            if file is None:
                raise PipelineError(f"detection image {image} is not in the manifest; re-run the detect stage")
            with Image.open(file) as im:
                pixels = np.asarray(im.convert("RGB"))
            for d in grp.itertuples():
                crop = pixels[
                    int(d.y0) : max(int(np.ceil(d.y1)), int(d.y0) + 1),
                    int(d.x0) : max(int(np.ceil(d.x1)), int(d.x0) + 1),
                ]
                label = (
                    d.label[2:] if d.label.startswith("a ") else (d.label[3:] if d.label.startswith("an ") else d.label)
                )
                text = _article(
                    f"{size_word(d.y1 - d.y0, d.img_height, small_max, medium_max)} {dominant_colour(crop)} {label}"
                )
                rows.append({"text": text, "category": d.category, "source": "images", "country": d.country})
                bar.advance(task)
    return rows


def build_descriptions(
    closed_set: Any,
    osm_objects: Any,
    dets: Any,
    image_files: dict[str, str],
    *,
    small_max: float = 0.15,
    medium_max: float = 0.4,
) -> Any:
    """Pure function of the stage: unique (text, category, source, country) with how many objects share it."""
    import pandas as pd

    rows = [
        {"text": t, "category": c, "source": "closed_set", "country": None}
        for t, c in zip(closed_set["prompt"], closed_set["category"], strict=True)
    ]
    signs = sign_table()
    for rec in osm_objects.to_dict("records"):
        rows.append(
            {
                "text": osm_description(rec, signs),
                "category": _tag(rec, "category"),
                "source": "osm",
                "country": rec["country"],
            }
        )
    rows += describe_detections(dets, image_files, small_max=small_max, medium_max=medium_max)
    df = pd.DataFrame(rows, columns=DESCRIPTION_COLUMNS[:-1])
    df["country"] = df["country"].astype("string")
    out = df.groupby(["text", "category", "source", "country"], dropna=False).size().rename("count").reset_index()
    return out.sort_values(["source", "country", "category", "text"], na_position="first").reset_index(drop=True)


def run(params_path: str | None = None) -> dict[str, int]:
    """Stage entry: write data/describe/descriptions.parquet and metrics.json."""
    import pandas as pd

    from pipelines.detect import read_manifest

    p = load_params(params_path, "describe")
    dets = pd.read_parquet(p["detections"])
    files: dict[str, str] = {}
    if not dets.empty:
        if not p["manifest"]:
            raise PipelineError("describe needs describe.manifest (the detect manifest) to read the detected images")
        man = read_manifest(p["manifest"], p["images_dir"] or None)
        files = dict(zip(man["path"], man["file"], strict=True))
    df = build_descriptions(
        pd.read_parquet(p["closed_set"]),
        pd.read_parquet(p["osm_objects"]),
        dets,
        files,
        small_max=float(p["small_max"]),
        medium_max=float(p["medium_max"]),
    )
    out = Path(p["out_dir"])
    write_table(df, out / "descriptions.parquet")
    metrics = {
        "descriptions_unique": len(df),
        "objects_described": int(df["count"].sum()),
        "descriptions_open_vocabulary": int(df["category"].isna().sum()),
    }
    for src in ("closed_set", "osm", "images"):
        metrics[f"objects_{src}"] = int(df.loc[df["source"] == src, "count"].sum())
    write_metrics(out / "metrics.json", metrics)
    return metrics


if __name__ == "__main__":
    stage_cli("describe", run)
