"""The cohabitants' global planner: a free-space graph over the walkable grid and lazy distance fields per goal site.

Roads are not walkable cells, so paths cross them only on crosswalks. Each goal site gets one Dijkstra run
(scipy, C speed) whose predecessor tree gives every cell its next step toward that site; agents sharing a
site share the field, so planning 100 agents costs at most `n_sites` Dijkstra runs.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from shapely.geometry import Polygon

from sim.scene.grid import SIDEWALK, grid_graph, obstacle_mask
from sim.scene.scene import Scene, as_scene


def boundary_segments(
    mask: np.ndarray, origin: np.ndarray, res: float
) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """Return the edges between True and False cells of `mask` as merged straight segments in world metres."""
    segs: list[tuple[tuple[float, float], tuple[float, float]]] = []
    padded = np.pad(mask, 1, constant_values=False)
    x0, y0 = float(origin[0]), float(origin[1])
    # Horizontal edges sit between rows; runs of consecutive differing columns merge into one segment.
    hdiff = padded[1:, 1:-1] != padded[:-1, 1:-1]  # (rows+1, cols)
    vdiff = padded[1:-1, 1:] != padded[1:-1, :-1]  # (rows, cols+1)
    for i, row in enumerate(hdiff):
        for start, end in _runs(row):
            y = y0 + i * res
            segs.append(((x0 + start * res, y), (x0 + end * res, y)))
    for j, col in enumerate(vdiff.T):
        for start, end in _runs(col):
            x = x0 + j * res
            segs.append(((x, y0 + start * res), (x, y0 + end * res)))
    return segs


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """Start (inclusive) and end (exclusive) indices of the runs of True in a 1-D bool array."""
    if not flags.any():
        return []
    step = np.diff(np.concatenate(([0], flags.astype(np.int8), [0])))
    return list(zip(np.flatnonzero(step == 1).tolist(), np.flatnonzero(step == -1).tolist()))


@dataclass
class NavGrid:
    """Walkable surfaces, object cells, the planning graph and cached distance fields for one scene."""

    cells: np.ndarray  # uint8 legend codes
    origin: np.ndarray
    res: float
    walkable: np.ndarray  # surfaces an agent centre may occupy (objects subtracted)
    free: np.ndarray  # planning cells: walkable, away from objects and edges, one connected component
    node_of: np.ndarray  # int32 [rows, cols] -> node id, -1 off the graph
    node_rc: np.ndarray  # int32 [n, 2] row, col of every node
    graph: csr_matrix
    nearest_rc: np.ndarray  # int32 [2, rows, cols]: nearest free cell of every cell
    sites: np.ndarray  # node ids of goal sites
    n_spread: int = 0  # the first n_spread sites are the farthest-point ones random goals are drawn from
    _dist: np.ndarray | None = None  # [sites, nodes] path length to each site, inf until computed
    _jump: np.ndarray | None = None
    _done: np.ndarray | None = None
    _centres: np.ndarray | None = None  # node_xy of every node, built on first use (agents look it up each tick)

    def __post_init__(self) -> None:
        if not self.n_spread:
            self.n_spread = len(self.sites)

    def add_site(self, node: int) -> int:
        """Index of the goal site at `node`, appending one (its field computed on first use) when there is none."""
        hit = np.flatnonzero(self.sites == node)
        if len(hit):
            return int(hit[0])
        self.sites = np.append(self.sites, np.int64(node))
        if self._dist is not None:
            dist, jump, done = self._tables()
            # Appended sites go after the spread ones, so random goal draws (over the first n_spread) do not change.
            self._dist = np.vstack([dist, np.full((1, self.n_nodes), np.inf)])
            self._jump = np.concatenate([jump, np.zeros((len(JUMPS), 1, self.n_nodes), dtype=np.int32)], 1)
            self._done = np.append(done, False)
        return len(self.sites) - 1

    def path_nodes(self, node: int, site: int, max_steps: int) -> np.ndarray:
        """Nodes of the shortest path from `node` toward `site` (at most max_steps + 1 of them, the site last)."""
        self.plan_all(np.array([site]))
        step = self._tables()[1][0, site]
        out = [int(node)]
        for _ in range(max_steps):
            nxt = int(step[out[-1]])
            if nxt == out[-1]:
                break
            out.append(nxt)
        return np.asarray(out, dtype=np.int64)

    @property
    def n_nodes(self) -> int:
        """Number of planning cells."""
        return int(self.node_rc.shape[0])

    @property
    def centres(self) -> np.ndarray:
        """World centres [n_nodes, 2] of every graph node."""
        if self._centres is None:
            rc = self.node_rc
            self._centres = np.stack(
                [self.origin[0] + (rc[:, 1] + 0.5) * self.res, self.origin[1] + (rc[:, 0] + 0.5) * self.res], -1
            )
        return self._centres

    @property
    def dist_table(self) -> np.ndarray:
        """[sites, nodes] path length in metres from every node to every goal site (inf until the site is planned)."""
        return self._tables()[0]

    @property
    def jump_table(self) -> np.ndarray:
        """[len(JUMPS), sites, nodes] node reached after JUMPS[j] steps toward every goal site (once it is planned)."""
        return self._tables()[1]

    def node_xy(self, nodes: np.ndarray) -> np.ndarray:
        """World centres [n, 2] of graph nodes."""
        return self.centres[nodes]

    def _frac(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fractional (column, row) grid coordinates of world points [n, 2]."""
        xy = np.atleast_2d(xy)
        return (xy[:, 0] - self.origin[0]) / self.res, (xy[:, 1] - self.origin[1]) / self.res

    def cell_of(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) of the cells holding world points [n, 2], clipped to the grid."""
        fx, fy = self._frac(xy)
        n_rows, n_cols = self.cells.shape
        # ndarray.clip and astype skip np.clip's Python dispatch: this runs several times per simulator tick.
        j = np.floor(fx).clip(0, n_cols - 1).astype(np.int64)
        i = np.floor(fy).clip(0, n_rows - 1).astype(np.int64)
        return i, j

    def inside(self, xy: np.ndarray) -> np.ndarray:
        """Whether world points lie inside the grid's extent."""
        fx, fy = self._frac(xy)
        n_rows, n_cols = self.cells.shape
        return (fx >= 0) & (fx < n_cols) & (fy >= 0) & (fy < n_rows)

    def is_walkable(self, xy: np.ndarray) -> np.ndarray:
        """Whether world points lie on a walkable cell that no object covers."""
        fx, fy = self._frac(xy)
        n_rows, n_cols = self.cells.shape
        inside = (fx >= 0) & (fx < n_cols) & (fy >= 0) & (fy < n_rows)
        return (
            inside
            & self.walkable[
                np.floor(fy).clip(0, n_rows - 1).astype(np.int64), np.floor(fx).clip(0, n_cols - 1).astype(np.int64)
            ]
        )

    def nearest_node(self, xy: np.ndarray) -> np.ndarray:
        """Graph node nearest to each world point (agents pushed off the graph snap back to it)."""
        i, j = self.cell_of(xy)
        return self.node_of[self.nearest_rc[0, i, j], self.nearest_rc[1, i, j]]

    def _tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        dist, jump, done = self._dist, self._jump, self._done
        if dist is None or jump is None or done is None:  # made together: all three or none
            k, n = len(self.sites), self.n_nodes
            dist = self._dist = np.full((k, n), np.inf)
            jump = self._jump = np.zeros((len(JUMPS), k, n), dtype=np.int32)  # node reached after 2^j steps
            done = self._done = np.zeros(k, dtype=bool)
        return dist, jump, done

    def plan_all(self, sites: np.ndarray) -> None:
        """Compute the distance fields of all `sites` not yet computed, in one Dijkstra call."""
        dist_t, jump_t, done = self._tables()
        if done[sites].all():
            return
        todo = np.unique(np.asarray(sites, dtype=np.int64))
        todo = todo[~done[todo]]
        if not len(todo):
            return
        dist, pred = dijkstra(self.graph, directed=True, indices=self.sites[todo], return_predecessors=True)
        dist, pred = np.atleast_2d(dist), np.atleast_2d(pred)
        own = np.arange(self.n_nodes, dtype=np.int32)
        for k, s in enumerate(todo):
            step = np.where(pred[k] >= 0, pred[k], own).astype(np.int32)  # the site (and unreachable) stay put
            dist_t[s] = dist[k]
            for j in range(len(JUMPS)):
                jump_t[j, s] = step
                step = step[step]  # composing the successor map doubles the look-ahead
            done[s] = True

    def field(self, site: int) -> np.ndarray:
        """Distance in metres from every node to `site` (computed once per site)."""
        self.plan_all(np.array([site]))
        return self._tables()[0][site]

    def distance(self, nodes: np.ndarray, sites: np.ndarray, planned: bool = False) -> np.ndarray:
        """Path length in metres from each node to its agent's goal site (`planned`: caller ran plan_all)."""
        if not planned:
            self.plan_all(sites)
        dist = self._dist
        assert dist is not None  # made by plan_all, here or by the caller
        return dist[sites, nodes]

    def lookahead(self, nodes: np.ndarray, sites: np.ndarray, steps: int, planned: bool = False) -> np.ndarray:
        """Node reached by following each agent's field `steps` (a power of two <= 8) cells toward its site."""
        if not planned:
            self.plan_all(sites)
        jump = self._jump
        assert jump is not None  # made by plan_all, here or by the caller
        return jump[JUMPS.index(steps), sites, nodes]

    def is_free(self, xy: np.ndarray) -> np.ndarray:
        """Whether world points lie on a planning cell (inside the grid, on the kept free component)."""
        fx, fy = self._frac(xy)
        n_rows, n_cols = self.cells.shape
        inside = (fx >= 0) & (fx < n_cols) & (fy >= 0) & (fy < n_rows)
        return (
            inside
            & self.free[
                np.floor(fy).clip(0, n_rows - 1).astype(np.int64), np.floor(fx).clip(0, n_cols - 1).astype(np.int64)
            ]
        )


JUMPS = [1, 2, 4, 8]


def build_navgrid(scene: Scene | Mapping[str, Any], *, plan_radius: float = 0.5, n_sites: int = 32) -> NavGrid:
    """Build the planning grid of a scene (a dict is parsed): object footprints inflated by `plan_radius`, goal
    sites spread out.

    A pure function of the scene, so one grid (and its distance fields) serves every episode in a scene.
    """
    scene = as_scene(scene)
    walk = scene.walkable
    cells, origin, res = walk.mask, np.asarray(walk.origin, dtype=np.float64), walk.resolution
    surface = cells > 0
    footprints = [Polygon(footprint) for footprint in scene.footprints()]
    # Agents keep the cells of objects thinner than a cell (cover_thin=False): ORCA sees those as obstacles.
    objects = obstacle_mask(walk, footprints, cover_thin=False)
    walkable = surface & ~objects
    inflated = obstacle_mask(walk, footprints, inflate=plan_radius, cover_thin=False, join_style="round")
    # Keep plans a body radius away from curbs and building edges, so ORCA obstacles are rarely touched.
    edge_clear = ndimage.distance_transform_edt(surface) * res > plan_radius
    free = surface & ~inflated & edge_clear
    labels, n_labels = ndimage.label(free, structure=np.ones((3, 3), dtype=bool))
    if n_labels == 0:
        raise ValueError("the scene has no walkable cell wide enough for agents; widen sidewalks or lower plan_radius")
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    free = labels == int(np.argmax(sizes))

    node_rc = np.argwhere(free).astype(np.int32)
    node_of = np.full(cells.shape, -1, dtype=np.int32)
    node_of[node_rc[:, 0], node_rc[:, 1]] = np.arange(len(node_rc), dtype=np.int32)
    graph = grid_graph(free, res, corner_cutting=False)
    _, idx = ndimage.distance_transform_edt(~free, return_indices=True)
    nearest_rc = idx.astype(np.int32)

    sidewalk_nodes = np.flatnonzero(cells[node_rc[:, 0], node_rc[:, 1]] == SIDEWALK)
    candidates = sidewalk_nodes if len(sidewalk_nodes) else np.arange(len(node_rc))
    sites = _spread_sites(node_rc[candidates].astype(np.float64), candidates, n_sites)
    return NavGrid(cells, origin, res, walkable, free, node_of, node_rc, graph, nearest_rc, sites)


def _spread_sites(rc: np.ndarray, candidates: np.ndarray, k: int) -> np.ndarray:
    """Pick `k` candidate nodes by farthest-point sampling from the first one, so goals cover the whole scene."""
    k = min(k, len(candidates))
    chosen = [0]
    dist = np.linalg.norm(rc - rc[chosen[0]], axis=1)
    for _ in range(k - 1):
        nxt = int(np.argmax(dist))
        chosen.append(nxt)
        dist = np.minimum(dist, np.linalg.norm(rc - rc[nxt], axis=1))
    return candidates[np.asarray(chosen)]
