"""Informative-view selection: the documented score, consensus with the other views, near-duplicates skipped, and
the contact sheet's frames and legend."""

from __future__ import annotations

import math

import numpy as np
import pytest

from retrieval.render import DUPLICATE_COS, consensus, contact_sheet, select_informative, view_statistics


def _object(colour, box=(8, 24, 10, 22), size: int = 32) -> np.ndarray:
    im = np.full((size, size, 3), 255, dtype=np.uint8)
    y0, y1, x0, x1 = box
    im[y0:y1, x0:x1] = colour
    im[y0 + 3 : y1 - 3, x0 + 2 : x1 - 2] = np.asarray(colour) // 2  # an inner panel: edges in both directions
    return im


def _reference_informativeness(image: np.ndarray) -> float:
    """The documented formula with numpy.gradient (what the OpenCV pass must equal)."""
    gray = image.astype(np.float32).mean(axis=2)
    fg = (image < 250).any(axis=2)
    gy, gx = np.gradient(gray)
    mag, ang = np.hypot(gx, gy), np.mod(np.arctan2(gy, gx), np.pi)
    sel = mag > 4.0
    hist, _ = np.histogram(ang[sel], bins=8, range=(0, np.pi), weights=mag[sel])
    prob = hist / hist.sum()
    nz = prob[prob > 0]
    return float(fg.mean()) * float(-(nz * np.log(nz)).sum() / math.log(8))


def test_informativeness_is_the_documented_formula():
    import tempfile
    from pathlib import Path

    from retrieval.aligned.dataset import render_asset

    with tempfile.TemporaryDirectory() as tmp:
        views, _ = render_asset("bench", 3, 4, 96, (15.0, 40.0), Path(tmp))
    for im in views:
        assert view_statistics(im)[0] == pytest.approx(_reference_informativeness(im), rel=1e-3)
    info, desc = view_statistics(np.full((16, 16, 3), 255, dtype=np.uint8))
    assert info == 0.0 and not desc.any()


def test_the_view_that_disagrees_with_the_others_has_the_least_consensus():
    views = [
        _object((200, 40, 40)),
        _object((200, 40, 40), (6, 26, 9, 23)),
        _object((190, 50, 40), (9, 23, 8, 24)),
        _object((40, 40, 200)),
    ]
    agree = consensus(np.stack([view_statistics(v)[1] for v in views]))
    assert int(np.argmin(agree)) == 3
    assert consensus(np.ones((1, 4))).tolist() == [1.0]


def test_selection_skips_a_near_duplicate_of_a_chosen_view():
    a = _object((200, 40, 40))
    views = [a, a.copy(), _object((190, 50, 40), (9, 23, 8, 24)), _object((180, 60, 50), (7, 25, 11, 21))]
    chosen, scores = select_informative(views, 2)
    assert scores[0] == scores[1]  # identical views, identical scores
    assert len(chosen) == 2 and not {0, 1} <= set(chosen)
    d = [view_statistics(views[i])[1] for i in chosen]
    assert float(d[0] @ d[1]) < DUPLICATE_COS
    assert select_informative([a, a.copy()], 2)[0] == [0, 1]  # nothing else to choose: duplicates fill up


def test_contact_sheet_frames_the_selected_views_and_has_a_legend():
    views = [_object((200, 40, 40)) for _ in range(6)]
    plain = contact_sheet(views, [1], cols=3)
    sheet = np.asarray(contact_sheet(views, [1], cols=3, scores=[0.1] * 6))
    assert sheet.shape[0] > np.asarray(plain).shape[0]  # the legend's rows under the grid
    assert tuple(sheet[1, 32 + 1]) == (0, 170, 0)  # view 1's green frame
    assert tuple(sheet[1, 1]) != (0, 170, 0)
