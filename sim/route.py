"""Reference routes: start and goal on the walkable area, a grid planner over the walkable mask minus
static obstacles inflated by the machine's half-width, smoothing, and progress / lateral offset along it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from sim.astar import astar_chain
from sim.scene.grid import SIDEWALK, grid_graph, obstacle_mask
from sim.scene.polyline import Polyline
from sim.scene.scene import Scene, as_scene

LONG_ROUTE = 120.0  # metres: longer routes are drawn as chained legs
# Scenes an env draws before a reset gives up: a scene of a large pool may hold no route of the asked length (a
# fragmented sidewalk network), and one such scene must not end a training run or an evaluation.
ROUTE_REDRAWS = 8


class RouteError(RuntimeError):
    """No route of the requested length exists in this scene for this machine."""


def _no_route(min_length: float, max_length: float, tries: int) -> RouteError:
    return RouteError(
        f"found no route between {min_length} and {max_length} m in {tries} tries; use a larger scene "
        "(more blocks) or a shorter `route_length`"
    )


class Route(Polyline):
    """The ego's reference route: a smoothed polyline resampled every `spacing` metres, from `start` to `goal`."""

    def __init__(self, points: np.ndarray, spacing: float = 0.25) -> None:
        pts = _resample(np.asarray(points, dtype=float), spacing)
        seg = np.diff(pts, axis=0)
        # Floored so that `locate` never divides by a zero-length segment.
        super().__init__(pts, np.maximum(np.hypot(seg[:, 0], seg[:, 1]), 1e-9))
        self.spacing = spacing

    @property
    def start(self) -> np.ndarray:
        """First point."""
        return self.points[0]

    @property
    def goal(self) -> np.ndarray:
        """Last point."""
        return self.points[-1]


def _resample(pts: np.ndarray, spacing: float) -> np.ndarray:
    seg = np.hypot(*np.diff(pts, axis=0).T)
    keep = np.concatenate([[True], seg > 1e-9])
    pts = pts[keep]
    arclen = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    if len(pts) < 2 or arclen[-1] <= 0:
        raise RouteError("a route needs two distinct points")
    n_steps = max(int(math.ceil(arclen[-1] / spacing)), 1)
    ss = np.linspace(0.0, arclen[-1], n_steps + 1)
    return np.stack([np.interp(ss, arclen, pts[:, 0]), np.interp(ss, arclen, pts[:, 1])], -1)


def _chaikin(pts: np.ndarray, iterations: int) -> np.ndarray:
    for _ in range(iterations):
        if len(pts) < 3:
            return pts
        quarter = 0.75 * pts[:-1] + 0.25 * pts[1:]
        three_quarter = 0.25 * pts[:-1] + 0.75 * pts[1:]
        mid = np.empty((2 * len(quarter), 2))
        mid[0::2], mid[1::2] = quarter, three_quarter
        pts = np.vstack([pts[:1], mid[1:-1], pts[-1:]])
    return pts


class RoutePlanner:
    """Grid planner for one scene and one machine width: samples start/goal pairs and plans smoothed routes."""

    def __init__(
        self, scene: Scene | Mapping[str, Any], half_width: float, margin: float = 0.25, comfort: float = 0.75
    ) -> None:
        self.scene = as_scene(scene)  # a dict is parsed (checked) here, once
        self.grid = grid = self.scene.walkable
        # Entrance steps block routes as objects do (a stair's footprint; rough and slick ground is drivable).
        steps = [terrain for terrain in self.scene.terrain if terrain["kind"] == "steps"]
        blocked = (grid.mask == 0) | obstacle_mask(grid, [*self.scene.objects, *steps])
        # Distance from each cell centre to the nearest blocked cell's edge, in metres.
        clearance = ndimage.distance_transform_edt(~blocked) * grid.resolution - 0.5 * grid.resolution
        free = clearance >= half_width + margin
        labels, n_labels = ndimage.label(free, structure=np.ones((3, 3)))
        if n_labels == 0:
            raise RouteError(f"no walkable cell is wide enough for a machine of half-width {half_width:.2f} m")
        sizes = np.bincount(labels.ravel())[1:]
        self.free = labels == (int(np.argmax(sizes)) + 1)  # keep the largest connected component
        self.clearance = clearance
        self.half_width = half_width
        rows, cols = np.nonzero(self.free)
        self.node = -np.ones(grid.shape, dtype=np.int64)
        self.node[rows, cols] = np.arange(len(rows))
        self.rows, self.cols = rows, cols
        # Edges near obstacles cost up to 3x their length, so routes keep to the middle of the clear path
        # when there is room, and squeeze past obstacles only when they must.
        prefer = half_width + margin + comfort
        self.penalty = 1.0 + 2.0 * np.clip(1.0 - clearance / prefer, 0.0, 1.0)
        self.graph = grid_graph(self.free, grid.resolution, cost=self.penalty)
        self._edge_rows: np.ndarray | None = None  # row of each stored edge (built on the first long route)
        sidewalk = grid.mask[rows, cols] == SIDEWALK
        candidates = np.nonzero(sidewalk)[0] if sidewalk.any() else np.arange(len(rows))
        # Per node: on a sidewalk; the nodes routes start and end on; their world (x, y).
        self._starts = (sidewalk, candidates, grid.cell_to_world(np.stack([rows[candidates], cols[candidates]], -1)))

    def _nearest_node(self, x: float, y: float) -> int:
        pts = self.grid.cell_to_world(np.stack([self.rows, self.cols], -1))
        k = int(np.argmin((pts[:, 0] - x) ** 2 + (pts[:, 1] - y) ** 2))
        if math.hypot(pts[k, 0] - x, pts[k, 1] - y) > 2.0:
            raise RouteError(
                f"({x:.2f}, {y:.2f}) is more than 2 m from any cell this machine can use; pick a point on a sidewalk"
            )
        return k

    def _route(self, chain: list[int], spacing: float) -> Route:
        cells = self.grid.cell_to_world(np.stack([self.rows[chain], self.cols[chain]], -1))
        # Keep every 4th cell (1 m at 0.25 m cells) and corner-cut: removes the 8-connected staircase.
        coarse = np.vstack([cells[:-1:4], cells[-1:]])
        return Route(_chaikin(coarse, 3), spacing)

    def plan(
        self, start: Sequence[float] | np.ndarray, goal: Sequence[float] | np.ndarray, spacing: float = 0.25
    ) -> Route:
        """The smoothed route between two given world points (each snapped to the nearest usable cell)."""
        start_node, goal_node = self._nearest_node(*start[:2]), self._nearest_node(*goal[:2])
        _, chain = astar_chain(self.graph, self.rows, self.cols, self.grid.resolution, start_node, goal_node, math.inf)
        if not chain:
            raise RouteError(f"no path from {list(start)} to {list(goal)} for this machine")
        return self._route(chain, spacing)

    def geodesic_length(self, route: Route, upto: float | None = None, step: float = 0.1) -> float:
        """Length of the shortest path from the route's start to its point at arc length `upto` (default: goal).

        The route's polyline is pulled taut (greedy line of sight) over the cells where the machine's centre
        fits (clearance >= its half-width): the shortest path in the route's homotopy class on the walkable
        grid, free of the planner's comfort margins. SPL and STL measure against it (docs/metrics.md).
        """
        end = route.length if upto is None else min(max(float(upto), 0.0), route.length)
        k = int(np.searchsorted(route.s, end, side="left"))
        pts = np.vstack([route.points[:k], route.point_at(end)[None]])
        if len(pts) < 2:
            return 0.0
        fits = self.clearance >= self.half_width - 0.5 * self.grid.resolution

        def visible(start: np.ndarray, end: np.ndarray) -> bool:
            n_samples = max(int(math.ceil(math.hypot(*(end - start)) / step)), 1)
            frac = np.linspace(0.0, 1.0, n_samples + 1)[:, None]
            rc = self.grid.world_to_cell(start + frac * (end - start))
            inside = self.grid.inside(rc)
            return bool(inside.all() and fits[rc[:, 0], rc[:, 1]].all())

        total, i = 0.0, 0
        while i < len(pts) - 1:
            # Farthest point still in line of sight: exponential search, then bisection.
            lo, hi = i + 1, i + 1
            while hi < len(pts) - 1 and visible(pts[i], pts[min(hi * 2 - i, len(pts) - 1)]):
                lo = hi = min(hi * 2 - i, len(pts) - 1)
            if hi < len(pts) - 1:
                hi = min(hi * 2 - i, len(pts) - 1)
                while hi - lo > 1:
                    mid = (lo + hi) // 2
                    if visible(pts[i], pts[mid]):
                        lo = mid
                    else:
                        hi = mid
            total += float(math.hypot(*(pts[lo] - pts[i])))
            i = lo
        return total

    def sample(
        self,
        rng: np.random.Generator,
        min_length: float = 5.0,
        max_length: float = 60.0,
        tries: int = 20,
        spacing: float = 0.25,
    ) -> Route:
        """Draw a start on a sidewalk cell and a goal on a sidewalk cell within `max_length` of it (straight line);
        plan it (A*, `sim.astar`) and keep it when its length is in [min, max], else draw both again.

        Routes longer than LONG_ROUTE (120 m) are chained legs (`_sample_legs`): in a 1-3 block scene no two
        points are 400 m apart, but a delivery round along both sides of the streets is.
        """
        sidewalk, candidates, xy = self._starts
        if min_length > LONG_ROUTE:
            return self._sample_legs(rng, min_length, max_length, candidates, sidewalk, spacing)
        for _ in range(tries):
            k = int(rng.integers(len(candidates)))
            near = np.nonzero(np.hypot(xy[:, 0] - xy[k, 0], xy[:, 1] - xy[k, 1]) <= max_length)[0]
            start, goal = int(candidates[k]), int(candidates[near[rng.integers(len(near))]])
            # Bounded so that a hopeless search ends early; above max_length because edges near obstacles cost up
            # to 3x their length.
            cost, chain = astar_chain(
                self.graph, self.rows, self.cols, self.grid.resolution, start, goal, 1.5 * max_length
            )
            if cost < min_length or not chain:
                continue
            route = self._route(chain, spacing)
            if min_length <= route.length <= max_length:
                return route
        raise _no_route(min_length, max_length, tries)

    def _without_recent(self, chain: list[int], cur: int, radius_m: float = 8.0) -> Any:
        """The graph without the cells within `radius_m` behind the chain's end, "behind" judged against both the
        heading of its last 1 m and of its last 3 m.

        A leg drawn on it cannot start by turning back: a wheeled machine without reverse cannot U-turn beside
        obstacles. One heading is not enough: a chain that ends with a 1 m hook (north after north-west) lets the
        next leg leave south-west, at right angles to the 3 m heading but 135 degrees from the hook. Cells just
        beside the end (within 0.5 m behind it) stay, so the end keeps its neighbours.
        """
        radius_cells = int(round(radius_m / self.grid.resolution))
        i0, j0 = int(self.rows[cur]), int(self.cols[cur])
        n_i, n_j = self.node.shape
        sl = (
            slice(max(i0 - radius_cells, 0), min(i0 + radius_cells + 1, n_i)),
            slice(max(j0 - radius_cells, 0), min(j0 + radius_cells + 1, n_j)),
        )
        ii, jj = np.mgrid[sl]
        behind = np.zeros(ii.shape, dtype=bool)
        for back_m in (1.0, 3.0):
            k = min(len(chain) - 1, int(back_m / self.grid.resolution))
            from_node, to_node = chain[-1 - k], chain[-1]
            heading = np.array(
                [self.cols[to_node] - self.cols[from_node], self.rows[to_node] - self.rows[from_node]], dtype=float
            )
            heading /= max(float(np.hypot(*heading)), 1e-9)
            behind |= (jj - j0) * heading[0] + (ii - i0) * heading[1] < -0.5 / self.grid.resolution
        behind &= (ii - i0) ** 2 + (jj - j0) ** 2 <= radius_cells * radius_cells
        nodes = self.node[sl][behind]
        keep = np.ones(self.graph.shape[0], dtype=bool)
        keep[nodes[nodes >= 0]] = False
        # The graph's edges between kept nodes, filtered in place of the CSR arrays (the same matrix as
        # diag(keep) @ graph @ diag(keep) without its zeros, at a fraction of two sparse products' cost).
        graph = self.graph
        if self._edge_rows is None:
            self._edge_rows = np.repeat(np.arange(graph.shape[0]), np.diff(graph.indptr))
        kept = keep[self._edge_rows] & keep[graph.indices]
        indptr = np.zeros(graph.shape[0] + 1, dtype=graph.indptr.dtype)
        np.cumsum(np.bincount(self._edge_rows[kept], minlength=graph.shape[0]), out=indptr[1:])
        return csr_matrix((graph.data[kept], graph.indices[kept], indptr), shape=graph.shape)

    def _goes_on(self, chain: list[int], cur: int, ahead_m: float = 20.0) -> bool:
        """Whether open space lies `ahead_m` onwards from the chain's end without turning back."""
        dist = dijkstra(self._without_recent(chain, cur), indices=cur, limit=2.0 * ahead_m)
        return bool((np.isfinite(dist) & (dist >= ahead_m)).any())

    def _sample_legs(
        self,
        rng: np.random.Generator,
        min_length: float,
        max_length: float,
        candidates: np.ndarray,
        sidewalk: np.ndarray,
        spacing: float,
        tries: int = 12,
    ) -> Route:
        """A long route as legs between sidewalk points, each leading away from where the last one began."""
        open_sidewalk = sidewalk & (self.penalty[self.rows, self.cols] <= 1.0)
        for _ in range(tries):
            target = float(rng.uniform(min_length, max_length))
            cur = int(candidates[rng.integers(len(candidates))])
            chain, total, prev = [cur], 0.0, None
            for _leg in range(16):
                remaining = target - total
                if remaining < 10.0:
                    break
                # A leg never starts back the way it came, and ends where the route can go on forwards (a dead end
                # would need a U-turn, which a wheeled machine without reverse cannot make beside obstacles).
                graph = self._without_recent(chain, cur) if len(chain) > 1 else self.graph
                # Costs grow up to 3x near obstacles: a leg's cost overstates its length, so aim a bit long.
                hi = 1.3 * remaining
                # Searched no further than `hi`: nodes beyond it cannot end the leg, and those within keep their
                # exact costs and predecessors (Dijkstra settles them before any farther one).
                dist, pred = dijkstra(graph, indices=cur, return_predecessors=True, limit=hi)
                ok = np.isfinite(dist) & open_sidewalk & (dist >= min(0.5 * hi, 40.0)) & (dist <= hi)
                if prev is not None:
                    ok &= prev > dist  # leads away from the previous leg's start
                pick = np.nonzero(ok)[0]
                leg: list[int] = []
                for nxt in pick[rng.permutation(len(pick))[:4]] if len(pick) else []:
                    cand = [int(nxt)]
                    while cand[-1] != cur:
                        cand.append(int(pred[cand[-1]]))
                    if remaining - float(dist[nxt]) < 10.0 or self._goes_on(chain + cand[::-1][1:], int(nxt)):
                        leg = cand
                        break
                if not leg:
                    break
                nxt = leg[0]
                chain += leg[::-1][1:]
                total += float(np.hypot(np.diff(self.rows[leg]), np.diff(self.cols[leg])).sum()) * self.grid.resolution
                prev, cur = dist, nxt
            if total < 0.8 * min_length:
                continue
            route = self._route(chain, spacing)
            if min_length <= route.length <= max_length:
                return route
        raise _no_route(min_length, max_length, tries)
