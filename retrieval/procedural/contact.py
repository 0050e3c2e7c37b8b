"""Contact sheet: a grid PNG of 3/4-view thumbnails of procedural assets, each labelled with its category."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from retrieval.procedural.export import ExportedAsset, export_asset
from retrieval.procedural.library import ProceduralAsset
from retrieval.procedural.views import render_views

LABEL_H = 18


def _pairs(assets: list, tmp: Path) -> list[tuple[ProceduralAsset, ExportedAsset]]:
    """Accept bare assets (exported into `tmp`) or (asset, exported) pairs."""
    out = []
    for i, item in enumerate(assets):
        if isinstance(item, ProceduralAsset):
            out.append((item, export_asset(item, tmp / f"{i:03d}_{item.category}")))
        elif isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], ProceduralAsset):
            out.append(item)
        else:
            raise TypeError(f"item {i} is {type(item).__name__}; pass ProceduralAsset or (asset, ExportedAsset)")
    return out


def contact_sheet(
    assets: list[ProceduralAsset] | list[tuple[ProceduralAsset, ExportedAsset]],
    out_png: Path,
    size: int = 160,
    azimuth: float = 35.0,
    elevation: float = 20.0,
) -> Path:
    """Render one labelled thumbnail per asset into a grid PNG at `out_png`; returns the path."""
    if not assets:
        raise ValueError("contact_sheet needs at least one asset")
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    cols = int(np.ceil(np.sqrt(len(assets) * 1.5)))
    rows = int(np.ceil(len(assets) / cols))
    sheet = Image.new("RGB", (cols * size, rows * (size + LABEL_H)), "white")
    draw = ImageDraw.Draw(sheet)
    font = ImageFont.load_default()
    with tempfile.TemporaryDirectory(prefix="curbside_sheet_") as tmp:
        for i, (asset, exported) in enumerate(_pairs(list(assets), Path(tmp))):
            (img,) = render_views(exported.obj_path, asset.dims, [azimuth], elevation, size)
            r, c = divmod(i, cols)
            x, y = c * size, r * (size + LABEL_H)
            sheet.paste(Image.fromarray(img), (x, y))
            label = asset.category
            tw = draw.textlength(label, font=font)
            draw.text((x + (size - tw) / 2, y + size + 3), label, fill=(20, 20, 20), font=font)
    sheet.save(out_png)
    return out_png
