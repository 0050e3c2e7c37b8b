"""The grids of every scene the envs use, packed in one flat uint8 array with per-scene offsets and frames, so that
one numpy gather reads any env's cells whatever its scene (`sim.batched.lidar` traces through it via `sim.raycast.march`, the env's
collision test reads the body and kind grids through it).
"""

from __future__ import annotations

import numpy as np

from sim.raycast.grids import WHAT, SceneGrids

KINDS = len(WHAT)  # the kind grid's index after the level tables


class Atlas:
    """Scene slots (`add` returns one, `remove` frees it) and, per slot, where each grid starts in `flat`."""

    def __init__(self, resolution: float) -> None:
        self.resolution = float(resolution)
        self.grids: list[SceneGrids | None] = []
        self.flat = np.zeros(0, dtype=np.uint8)
        self.offset = np.zeros((0, 2, KINDS + 1), dtype=np.int64)  # slot, level, table (KINDS: the kind grid)
        self.x0 = np.zeros(0)
        self.y0 = np.zeros(0)
        self.cols = np.zeros(0, dtype=np.int64)
        self.rows = np.zeros(0, dtype=np.int64)

    def add(self, grids: SceneGrids) -> int:
        """A slot for one scene's grids (a freed slot first)."""
        if grids.resolution != self.resolution:
            raise ValueError(f"grids at {grids.resolution} m in an atlas of {self.resolution} m cells")
        free = [k for k, g in enumerate(self.grids) if g is None]
        if free:
            slot = free[0]
            self.grids[slot] = grids
        else:
            slot = len(self.grids)
            self.grids.append(grids)
        self._pack()
        return slot

    def remove(self, slot: int) -> None:
        """Free a slot (its scene is no longer used by any env)."""
        self.grids[slot] = None
        self._pack()

    def _pack(self) -> None:
        n = len(self.grids)
        self.offset = np.zeros((n, 2, KINDS + 1), dtype=np.int64)
        self.x0, self.y0 = np.zeros(n), np.zeros(n)
        self.cols, self.rows = np.ones(n, dtype=np.int64), np.ones(n, dtype=np.int64)
        parts, at = [], 0
        for k, g in enumerate(self.grids):
            if g is None:
                continue
            self.x0[k], self.y0[k] = g.origin
            self.rows[k], self.cols[k] = g.shape
            for level, tables in enumerate(g.tables):
                for j, table in enumerate([*tables, g.kinds]):
                    if j == KINDS and level == 1:
                        self.offset[k, 1, KINDS] = self.offset[k, 0, KINDS]  # one kind grid for both levels
                        continue
                    self.offset[k, level, j] = at
                    parts.append(table.ravel())
                    at += table.size
        if at >= 2**31:
            raise MemoryError(f"the scenes' grids hold {at} cells, past the 2**31 the tracer indexes; use fewer scenes "
                              "(scene_cache) or a coarser lidar.resolution")
        self.flat = np.concatenate(parts) if parts else np.zeros(0, dtype=np.uint8)

    def frames(self, slots: np.ndarray, level: np.ndarray, what: str) -> dict[str, np.ndarray]:
        """Per-env frames of grid `what` (a WHAT name or "kinds") at each env's slot and level."""
        k = KINDS if what == "kinds" else WHAT.index(what)
        return {"offset": self.offset[slots, level, k], "x0": self.x0[slots], "y0": self.y0[slots],
                "cols": self.cols[slots], "rows": self.rows[slots]}

    def lookup(self, frame: dict[str, np.ndarray], x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Grid values at world points x, y [n, k] of n envs (clamped onto each grid: its ring outside)."""
        inv = 1.0 / self.resolution
        col = np.clip(((x - frame["x0"][:, None]) * inv).astype(np.int64), 0, frame["cols"][:, None] - 1)
        row = np.clip(((y - frame["y0"][:, None]) * inv).astype(np.int64), 0, frame["rows"][:, None] - 1)
        return self.flat[frame["offset"][:, None] + row * frame["cols"][:, None] + col]
