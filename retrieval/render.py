"""Multi-view rendering on CPU with PyBullet's TinyRenderer, informative-view selection and contact sheets.

Informative-view criterion (docs/retrieval.md): score = coverage x edge_entropy x consensus.
- coverage: the fraction of pixels covered by the object; edge_entropy: the normalised Shannon entropy of the
  magnitude-weighted gradient-orientation histogram (8 bins) over the object's pixels. A large silhouette with
  edges in many directions (a bench seen three-quarter) beats a thin or edge-on view (a bench seen end-on).
- consensus: how well the view agrees with the object's other views (cosine of its OpenCV appearance descriptor,
  colour + edge-orientation histograms, with the mean of the others). This follows Luo et al. (2024, DiffuRank),
  who keep the views whose content best explains the whole object: there a text-to-3D diffusion model measures
  the agreement, here a cheap descriptor does, so all 20 views can be ranked at render cost. Views that show an
  atypical part only (the underside, a pole's cap from above) agree least.
Selected views are then kept apart: a view nearly identical to one already chosen (a symmetric object's mirror
view) is passed over, as Luo et al. (2023, Cap3D) spread captioning views around the object.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from retrieval.defaults import MAX_VIEWS


@dataclass(frozen=True)
class ViewSpec:
    """Camera placement of one view: azimuth from +x (front) counter-clockwise, elevation above the horizon, degrees."""

    azimuth: float
    elevation: float


def view_specs(n_views: int = 8, elevations: tuple[float, float] = (15.0, 40.0)) -> list[ViewSpec]:
    """Spread `n_views` over two elevations; the second ring is offset half a step so no azimuth repeats."""
    if not 1 <= n_views <= MAX_VIEWS:
        raise ValueError(f"n_views must be in 1..{MAX_VIEWS}, got {n_views}; lower it or raise MAX_VIEWS")
    low = (n_views + 1) // 2
    high = n_views - low
    specs = [ViewSpec(round(i * 360.0 / low + 30.0, 3) % 360.0, elevations[0]) for i in range(low)]
    if high:
        specs += [
            ViewSpec(round(i * 360.0 / high + 30.0 + 180.0 / high, 3) % 360.0, elevations[1]) for i in range(high)
        ]
    return specs


@lru_cache(maxsize=1)
def _client() -> int:
    """One DIRECT PyBullet client per process: connecting costs more than rendering a view."""
    from kernel.quiet import import_pybullet

    p = import_pybullet()

    return p.connect(p.DIRECT)


def obj_bounds(obj_path: str | Path) -> np.ndarray:
    """(2, 3) min/max corner of the vertices of an OBJ file."""
    verts = [line.split()[1:4] for line in Path(obj_path).read_text().splitlines() if line.startswith("v ")]
    v = np.asarray(verts, dtype=np.float64)
    return np.stack([v.min(axis=0), v.max(axis=0)])


def render_obj(
    obj_path: str | Path,
    specs: list[ViewSpec],
    size: int = 224,
    fov: float = 40.0,
    bounds: np.ndarray | None = None,
) -> list[np.ndarray]:
    """Render a textured OBJ (z-up) from each view on a white background; returns HxWx3 uint8 images."""
    from kernel.quiet import import_pybullet

    p = import_pybullet()

    cid = _client()
    vis = p.createVisualShape(p.GEOM_MESH, fileName=str(obj_path), physicsClientId=cid)
    if vis < 0:
        raise RuntimeError(f"PyBullet could not load {obj_path}; check that the OBJ and its MTL exist")
    body = p.createMultiBody(baseMass=0, baseVisualShapeIndex=vis, physicsClientId=cid)
    try:
        # A visual-only body has an empty AABB, so the camera frames the mesh's own bounds.
        lo, hi = np.asarray(bounds if bounds is not None else obj_bounds(obj_path), dtype=np.float64)
        centre = (lo + hi) / 2
        radius = max(float(np.linalg.norm(hi - lo)) / 2, 1e-6)
        # Distance at which the bounding sphere fills the vertical field of view with a small margin.
        dist = radius / math.sin(math.radians(fov / 2)) * 1.02
        proj = p.computeProjectionMatrixFOV(fov, 1.0, dist * 0.05, dist * 3.0, physicsClientId=cid)
        images = []
        for s in specs:
            view = p.computeViewMatrixFromYawPitchRoll(
                centre.tolist(),
                dist,
                yaw=s.azimuth + 90.0,
                pitch=-s.elevation,
                roll=0,
                upAxisIndex=2,
                physicsClientId=cid,
            )
            _, _, rgba, _, seg = p.getCameraImage(
                size,
                size,
                view,
                proj,
                renderer=p.ER_TINY_RENDERER,
                shadow=0,
                lightDirection=[1.0, 0.6, 2.0],
                physicsClientId=cid,
            )
            rgb = np.asarray(rgba, dtype=np.uint8).reshape(size, size, 4)[:, :, :3].copy()
            mask = np.asarray(seg).reshape(size, size) < 0
            rgb[mask] = 255
            images.append(rgb)
        return images
    finally:
        p.removeBody(body, physicsClientId=cid)


DUPLICATE_COS = 0.995  # descriptor cosine above which a view repeats one already selected
DESCRIPTOR_DIM = 8 * 4 + 16


def foreground(image: np.ndarray) -> np.ndarray:
    """Boolean mask of the object's pixels: any channel below 250 (renders have a pure white background)."""
    import cv2

    return cv2.inRange(image, (250, 250, 250), (255, 255, 255)) == 0  # OpenCV's range test: ~20x numpy's


def view_statistics(image: np.ndarray) -> tuple[float, np.ndarray]:
    """(informativeness, unit appearance descriptor) of a view, from one gradient pass (OpenCV).

    informativeness: foreground coverage times the entropy of the magnitude-weighted gradient-orientation histogram
    (8 bins over pixels with |grad| > 4, normalised to [0, 1]); 0 for an empty view. Descriptor: the hue-saturation
    histogram of the object's pixels (8 x 4) and the magnitude-weighted edge-orientation histogram of the same edge
    pixels (16 bins), each summing to 1, then unit length; zeros for an empty view.
    """
    import cv2

    fg = foreground(image)
    coverage = float(np.count_nonzero(fg)) / fg.size
    if coverage == 0.0:
        return 0.0, np.zeros(DESCRIPTOR_DIM, dtype=np.float32)
    gray = image.astype(np.float32) @ np.full(3, 1 / 3, dtype=np.float32)  # the channel mean
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0, ksize=1, scale=0.5)  # central differences (numpy.gradient's interior)
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1, ksize=1, scale=0.5)
    sel = gx * gx + gy * gy > 16.0  # |grad| > 4: the edge pixels, a small part of the view
    info = 0.0
    edges: np.ndarray = np.zeros(16)  # float64 weighted counts, though numpy types bincount's result as intp
    if sel.any():
        ex, ey = gx[sel], gy[sel]
        # numpy's arctan2, not cv2.cartToPolar: the latter puts an exactly horizontal edge at 2pi - eps, not 0.
        mag, ang = np.hypot(ex, ey), np.mod(np.arctan2(ey, ex), np.pi)
        hist = np.bincount(np.minimum((ang * (8 / np.pi)).astype(np.int64), 7), weights=mag, minlength=8)
        prob = hist / max(hist.sum(), 1e-9)
        nz = prob[prob > 0]
        info = coverage * float(-(nz * np.log(nz)).sum() / math.log(8))
        edges = np.bincount(np.minimum((ang * (16 / np.pi)).astype(np.int64), 15), weights=mag, minlength=16)
    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)
    colour = cv2.calcHist([hsv], [0, 1], fg.astype(np.uint8), [8, 4], [0, 180, 0, 256]).ravel()
    d = np.concatenate([colour / max(colour.sum(), 1e-9), edges / max(edges.sum(), 1e-9)]).astype(np.float32)
    return info, d / max(float(np.linalg.norm(d)), 1e-12)


def consensus(descriptors: np.ndarray) -> np.ndarray:
    """Per view, the cosine of its descriptor with the mean descriptor of the other views (1 for a single view)."""
    d = np.asarray(descriptors, dtype=np.float64)
    n = len(d)
    if n < 2:
        return np.ones(n)
    others = (d.sum(0)[None] - d) / (n - 1)
    norm = np.linalg.norm(others, axis=1) * np.linalg.norm(d, axis=1)
    return np.where(norm > 0, (d * others).sum(1) / np.maximum(norm, 1e-12), 0.0)


def select_informative(images: list[np.ndarray], k: int) -> tuple[list[int], list[float]]:
    """Indices of the `k` most informative views (coverage x edge entropy x consensus; ties to the lower index;
    near-duplicates of a chosen view skipped while others remain) and every view's score."""
    stats = [view_statistics(im) for im in images]
    desc = np.stack([d for _, d in stats])
    agree = consensus(desc)
    scores = [round(info * float(a), 9) for (info, _), a in zip(stats, agree)]
    order = sorted(range(len(images)), key=lambda i: (-scores[i], i))
    chosen: list[int] = []
    for i in order:
        if len(chosen) == max(1, k):
            break
        if all(float(desc[i] @ desc[j]) < DUPLICATE_COS for j in chosen):
            chosen.append(i)
    for i in order:  # fewer distinct views than k: fill with the best remaining ones
        if len(chosen) < min(max(1, k), len(images)) and i not in chosen:
            chosen.append(i)
    return sorted(chosen), scores


LEGEND = (
    "green frame: selected for scoring; number: view score = coverage x edge entropy x consensus with the "
    "other views (Luo et al. 2024); near-duplicates of a selected view are skipped"
)


def contact_sheet(
    images: list[np.ndarray],
    selected: list[int] | None = None,
    cols: int = 5,
    title: str | None = None,
    scores: list[float] | None = None,
):
    """Grid of the views as a PIL image: selected (informative) views framed green, each view's score in its
    corner, and a legend saying how the views were chosen."""
    from PIL import Image, ImageDraw

    h, w = images[0].shape[:2]
    cols = min(cols, len(images))
    rows = math.ceil(len(images) / cols)
    top = 18 if title else 0
    bottom = 30 if scores is not None else 0
    sheet = Image.new("RGB", (cols * w, rows * h + top + bottom), "white")
    draw = ImageDraw.Draw(sheet)
    if title:
        draw.text((4, 3), title[:120], fill=(0, 0, 0))
    for i, im in enumerate(images):
        x, y = (i % cols) * w, (i // cols) * h + top
        sheet.paste(Image.fromarray(im), (x, y))
        if selected and i in selected:
            draw.rectangle([x + 1, y + 1, x + w - 2, y + h - 2], outline=(0, 170, 0), width=3)
        if scores is not None:
            draw.text(
                (x + 5, y + 4),
                f"{i}: {scores[i]:.2f}",
                fill=(0, 120, 0) if selected and i in selected else (90, 90, 90),
            )
    if scores is not None:
        import textwrap

        for n, line in enumerate(textwrap.wrap(LEGEND, width=max(20, cols * w // 6))[:2]):
            draw.text((4, rows * h + top + 2 + 13 * n), line, fill=(0, 0, 0))
    return sheet
