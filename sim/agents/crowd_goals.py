"""Goal following on the navigation grid: drawing goals, arrival, progress, stalls, preferred velocities.

Functions of the crowd's state (sim.agents.crowd_state.CrowdState), the scene's navigation grid, the episode's
random generator and the agents config; AgentManager calls them and hands `new_goal`, bound to its parts, to the
behaviours as a GoalSetter.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from sim.agents.crowd_kernels import carrots, headings, idle_tick, progress, rungs
from sim.agents.crowd_state import CrowdState
from sim.agents.kinds import AGENT_KINDS, IDLE, KIND_NAMES, RUNNING, WALKING
from sim.agents.navgrid import JUMPS, NavGrid

if TYPE_CHECKING:  # pragma: no cover - typing only; behaviours imports this module
    from sim.agents.behaviours import Crossings, Groups


class GoalSetter(Protocol):
    """Sends agent i (at planning node `node`) to a new goal; the keywords as new_goal's."""

    def __call__(
        self,
        i: int,
        node: int,
        *,
        abandon: bool = False,
        site: int | None = None,
        goal_xy: np.ndarray | None = None,
        speed: float | None = None,
    ) -> None: ...


class GoalCells:
    """Goal cells around each goal site, cached per grid: goals are drawn among them every time an agent heads there."""

    def __init__(self) -> None:
        self._cells: dict[tuple[int, int, float], np.ndarray] = {}  # (id(grid), site, spread) -> node ids

    def clear(self) -> None:
        """Forget every cached set (a new scene)."""
        self._cells = {}

    def near(self, grid: NavGrid, site: int, spread: float, dist: np.ndarray) -> np.ndarray:
        """Nodes within `spread` m of goal site `site` (and within 1.5 spread along its field `dist`)."""
        key = (id(grid), site, spread)
        cells = self._cells.get(key)
        if cells is None:
            centre = grid.node_xy(np.array([grid.sites[site]]))[0]
            cand = np.flatnonzero(dist < spread * 1.5)
            cells = cand[np.flatnonzero(np.linalg.norm(grid.node_xy(cand) - centre, axis=1) < spread)]
            self._cells[key] = cells
        return cells


def walking_speed(state: CrowdState, i: int, rng: np.random.Generator) -> float:
    """A fresh walking speed for agent i's kind."""
    return AGENT_KINDS[KIND_NAMES[state.kind_idx[i]]].sample_speed(rng, "walking")


def new_goal(
    state: CrowdState,
    grid: NavGrid,
    rng: np.random.Generator,
    config: Mapping[str, Any],
    crossings: Crossings,
    cells: GoalCells,
    i: int,
    node: int,
    *,
    abandon: bool = False,
    site: int | None = None,
    goal_xy: np.ndarray | None = None,
    speed: float | None = None,
) -> None:
    """Send agent i (at `node`) to a random goal, or to `site` (its cell nearest `goal_xy`) walking at `speed`.

    A random goal lies across a road (over `crossings`) with chance `cross_prob`; `abandon` counts the goal it
    leaves as abandoned. The goal's time budget starts now.
    """
    spread = config["goal_spread"]
    state.crossing[i] = False
    # cross_prob 0 draws nothing, so runs without crossings keep their random stream.
    if site is None and config["cross_prob"] > 0 and rng.random() < config["cross_prob"]:
        site = crossings.pick(state.pos[i])
        if site is not None:
            state.crossing[i] = True
            state.cross_counts["started"] += 1
            spread = min(spread, 1.0)  # stay by the crosswalk's far end, not 2.5 m around it
    if site is None:
        spread_sites = grid.sites[: grid.n_spread]  # crossing sites are goals of crossings only
        here = int(np.argmin(np.linalg.norm(grid.node_xy(spread_sites) - state.pos[i], axis=1)))
        choices = np.delete(np.arange(len(spread_sites)), here) if len(spread_sites) > 1 else np.arange(1)
        site = int(rng.choice(choices))
    if abandon:
        state.counts["abandoned"] += 1
    if speed is None:
        kind = AGENT_KINDS[KIND_NAMES[state.kind_idx[i]]]
        run = kind.run_speed is not None and rng.random() < config["run_prob"]
        state.movement[i] = RUNNING if run else WALKING
        state.speed[i] = kind.sample_speed(rng, "running" if run else "walking")
    else:
        state.movement[i], state.speed[i] = WALKING, speed
    dist = grid.field(site)
    if goal_xy is None:
        near_nodes = cells.near(grid, site, spread, dist)
        goal_node = int(rng.choice(near_nodes)) if len(near_nodes) else int(grid.sites[site])
    else:
        goal_node = int(grid.nearest_node(np.asarray(goal_xy, dtype=np.float64)[None])[0])
    state.site[i] = site
    state.goal[i] = grid.node_xy(np.array([goal_node]))[0]
    length = float(dist[node]) + config["goal_spread"]
    state.goal_t0[i] = state.time
    state.budget[i] = config["budget_factor"] * length / max(state.speed[i], 0.1) + config["budget_slack"]
    state.best[i] = np.inf
    state.stall[i] = 0


def update_goals(
    state: CrowdState,
    grid: NavGrid,
    rng: np.random.Generator,
    config: Mapping[str, Any],
    groups: Groups,
    set_goal: GoalSetter,
    dt: float,
    nodes: np.ndarray,
) -> None:
    """Count down idle agents, then settle the moving ones' arrivals and abandoned goals (agents at `nodes`).

    An idle agent whose time is up leaves for a new goal (a group member: its group decides); one that arrived
    idles with chance `idle_prob` or takes a new goal; one stuck for `regoal_steps` abandons its goal.
    """
    for i in idle_tick(state.movement, state.idle_left, float(dt), IDLE).tolist():
        if state.movement[i] != IDLE:
            continue  # its group's decision already sent it off
        if groups.of[i] >= 0:
            groups.stand_over(state, rng, config, i, nodes, set_goal)
        else:
            set_goal(i, int(nodes[i]))
    moving = np.flatnonzero(state.movement != IDLE)
    if not len(moving):
        return
    arrived, abandon = progress(
        moving,
        state.pos,
        state.goal,
        nodes,
        state.site,
        grid.dist_table,
        state.stall,
        state.best,
        float(config["arrive_radius"]),
        float(config["crowded_arrive_radius"]),
        int(config["stuck_steps"]),
        float(config["stuck_progress"]),
        int(config["regoal_steps"]),
    )  # new_goal planned every field
    if arrived.any():
        for i in moving[arrived].tolist():
            late = state.time - state.goal_t0[i] > state.budget[i]
            state.counts["late" if late else "in_time"] += 1
            state.cross_counts["done"] += int(state.crossing[i])
            state.crossing[i] = False
            if groups.of[i] >= 0:
                groups.arrived(state, rng, config, i)
            elif rng.random() < config["idle_prob"]:
                state.movement[i] = IDLE
                state.idle_left[i] = rng.uniform(*config["idle_time"])
            else:
                set_goal(i, int(nodes[i]))
    for i in moving[abandon].tolist():
        if groups.of[i] >= 0:
            groups.dissolve(state, int(groups.of[i]))
        set_goal(i, int(nodes[i]), abandon=True)


def preferred(
    state: CrowdState,
    grid: NavGrid,
    config: Mapping[str, Any],
    visible: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
    nodes: np.ndarray,
    idx: np.ndarray,
) -> np.ndarray:
    """Preferred velocities [len(idx), 2] of agents `idx` (at `nodes`): toward a carrot ahead on their goal field.

    `visible(p, q, r)` says whether discs of radii r [k] see points q [k, 2] from p [k, 2] past the obstacles (ORCA's
    visibility query).
    An agent stalled for `stuck_steps` side-steps (the rotate half of push-and-rotate).
    """
    sites = state.site[idx]
    pos = state.pos[idx]
    steps = config["lookahead_cells"]
    ox, oy = float(grid.origin[0]), float(grid.origin[1])
    # Keep right: shortest paths hug the same inner edges in both directions, so opposing flows would meet
    # head-on in one lane (ORCA then herds the weaker side backwards); a right offset forms two lanes.
    jumps = grid.jump_table
    carrot = carrots(
        idx,
        nodes,
        state.pos,
        state.site,
        jumps[JUMPS.index(steps)],
        grid.centres,
        float(config["keep_right"]),
        ox,
        oy,
        float(grid.res),
        grid.free,
    )
    # A carrot behind a concave corner (a crosswalk mouth) would press the agent into the curb: fall back
    # to nearer points of the path (steps, steps/2, ..., 1 cells; the last without a check) until one is in
    # sight. The rungs are looked up at once for the few agents that need them.
    radius = state.radius[idx]
    blocked = np.flatnonzero(~visible(pos, carrot, radius))
    if blocked.size:
        ladder = rungs(nodes[blocked], sites[blocked], jumps, grid.centres, JUMPS.index(steps))
        todo = np.ones(blocked.size, dtype=bool)  # still looking for a rung in sight
        for rung in ladder[:-1]:
            seen = np.zeros(blocked.size, dtype=bool)
            seen[todo] = visible(pos[blocked[todo]], rung[todo], radius[blocked[todo]])
            carrot[blocked[seen]] = rung[seen]
            todo &= ~seen
        carrot[blocked[todo]] = ladder[-1][todo]
    # Close to the site the field's single target cell would pull everyone to one point: aim at the own goal.
    direction, speed = headings(
        idx, nodes, state.pos, carrot, state.goal, state.site, grid.dist_table, state.speed, 1.5 * config["goal_spread"]
    )
    stall = state.stall[idx]
    stuck = stall >= config["stuck_steps"]
    if stuck.any():
        # Side-step (the rotate half of push-and-rotate): to the right when there is room, else to the left,
        # switching sides every `stuck_steps` so an agent pinned against a curb or a wall gets out.
        dx, dy = direction[stuck, 0].copy(), direction[stuck, 1].copy()
        right = np.stack([dy, -dx], 1)
        probe = pos[stuck] + right * 1.0
        sign = np.where(grid.is_free(probe), 1.0, -1.0)
        phase = (stall[stuck] - config["stuck_steps"]) // config["stuck_steps"]
        sign = np.where(phase % 2 == 1, -sign, sign)
        ang = -1.2 * sign
        cs, sn = np.cos(ang), np.sin(ang)
        direction[stuck, 0], direction[stuck, 1] = cs * dx - sn * dy, sn * dx + cs * dy
    return direction * speed[:, None]
