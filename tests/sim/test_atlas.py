"""The batched env's grid atlas: scenes coming and going leave gaps; the atlas closes them before it would pass the
cells the tracer can index, and every scene in use reads the same cells afterwards."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from sim.batched.atlas import Atlas
from sim.raycast.grids import WHAT

TABLES = 2 * len(WHAT) + 1  # two levels of WHAT tables, and the kind grid


def _grids(rows: int, value: int) -> SimpleNamespace:
    """A scene's grids of `rows` x 4 cells a table, every table filled with its own value."""
    table = lambda k: np.full((rows, 4), (value + k) % 251, dtype=np.uint8)  # noqa: E731
    return SimpleNamespace(
        resolution=0.1,
        origin=(0.0, 0.0),
        shape=(rows, 4),
        tables=[[table(j) for j in range(len(WHAT))], [table(len(WHAT) + j) for j in range(len(WHAT))]],
        kinds=table(2 * len(WHAT)),
    )


def _cells(atlas: Atlas, slot: int, rows: int) -> np.ndarray:
    """Every cell of every WHAT table at both levels, and the kind grid, of the scene in `slot`."""
    x, y = np.meshgrid(np.arange(4) * 0.1 + 0.05, np.arange(rows) * 0.1 + 0.05)
    x, y = x.reshape(1, -1), y.reshape(1, -1)
    out = []
    for level in (0, 1):
        for what in (*WHAT, "kinds"):
            frame = atlas.frames(np.array([slot]), np.array([level]), what)
            out.append(atlas.lookup(frame, x, y))
    return np.concatenate(out, axis=1)


def test_gaps_left_by_removed_scenes_are_closed_before_the_index_limit() -> None:
    atlas = Atlas(0.1)
    unit = TABLES * 4  # cells a row of a scene takes
    atlas.max_cells = 10 * unit
    small_a, big_b, small_c, big_d = (atlas.add(_grids(r, v)) for r, v in ((1, 10), (3, 20), (1, 30), (3, 40)))
    before = {slot: _cells(atlas, slot, rows) for slot, rows in ((big_b, 3), (big_d, 3))}
    atlas.remove(small_a)
    atlas.remove(small_c)
    # 8 rows in use after gaps of 1: a 3-row scene fits in no gap, and at the end it would pass 10 rows.
    big_e = atlas.add(_grids(3, 50))
    assert atlas.used == 9 * unit  # the three scenes in use, packed from the start
    for slot, cells in before.items():
        assert np.array_equal(_cells(atlas, slot, 3), cells)
    assert np.array_equal(_cells(atlas, big_e, 3), _cells_of(_grids(3, 50)))
    with pytest.raises(MemoryError, match="past the"):
        atlas.add(_grids(2, 60))  # 11 rows in use would pass the limit however they are packed


def _cells_of(grids: SimpleNamespace) -> np.ndarray:
    """The same cells read straight from a scene's own tables, in `_cells`' order."""
    flat = [t.reshape(1, -1) for level in grids.tables for t in (*level, grids.kinds)]
    return np.concatenate(flat, axis=1)
