"""The lifecycle every env manager shares, and the explicit inputs each of its hooks gets.

A manager runs one part of the world besides the machine (SocialNav: the crowd, the traffic, their bodies). The
env holds them in `env.managers` and calls each hook on every manager in list order, so a manager listed later
sees what the earlier ones did in the same hook. Hooks get small context objects, never the env:

| hook | when |
|---|---|
| `on_scene(SceneContext)` | a new world is built: make this manager's state for it (bodies, scene planners) |
| `leave_scene() -> state` | the env leaves the world for another cached one; the state is kept with the world |
| `enter_scene(state)` | the env comes back to a cached world: use the state `leave_scene` returned there |
| `park()` | at reset, before the start's surface height is probed: move bodies out of the way |
| `reset(ResetContext)` | at reset, once the machine stands at the route's start |
| `before_step(TickContext)` | every step, before the machine's physics substeps |
| `after_step(TickContext)` | every step, after the physics substeps and before sensing (the LiDAR then sees it) |
| `view_fields()` | at reset: `EpisodeView` fields this manager supplies to the measures |
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import numpy as np

from sim.route import Route
from sim.scene.scene import Scene
from sim.sensors import GridLidar, Lidar

S = TypeVar("S")


@dataclass(frozen=True)
class EgoPose:
    """The machine as the managers see it, read after its last physics substep."""

    x: float
    y: float
    yaw: float  # radians
    speed: float  # m/s along the heading
    length: float  # footprint, metres
    width: float


@dataclass(frozen=True)
class SceneContext:
    """A world just built: its scene, its Bullet client, its LiDARs and its body-kind table."""

    scene: Scene
    client: int
    lidars: tuple[Lidar | GridLidar, ...]  # the world's LiDARs (high, then low where configured)
    collision_kinds: dict[int, str]  # body id -> collision kind; a manager enters the bodies it adds


@dataclass(frozen=True)
class ResetContext:
    """An episode's start: its scene and route, the machine placed at the start, and the reset's RNG."""

    scene: Scene
    rng: np.random.Generator  # the env's episode RNG: every draw of an episode comes from it, in hook order
    ego: EgoPose
    route: Route


@dataclass(frozen=True)
class TickContext:
    """One env step: its length and the machine (before the physics in `before_step`, after it in `after_step`)."""

    dt: float  # seconds
    ego: EgoPose
    action: tuple[float, float]  # the clipped (steering, throttle_brake) of the step


class Manager(Generic[S]):
    """Base of an env manager: every hook does nothing; a manager overrides the ones it needs.

    `S` is the manager's per-world state: what `leave_scene` returns and `enter_scene` takes back.
    """

    def on_scene(self, ctx: SceneContext) -> None:
        """A new world is built in `ctx.client`: make and use this manager's state for it."""

    def leave_scene(self) -> S | None:
        """The env leaves the current world: return its state (kept with the cached world)."""
        return None

    def enter_scene(self, state: S | None) -> None:
        """The env is back in a cached world: use `state`, what `leave_scene` returned there."""

    def park(self) -> None:
        """At reset, before the start's surface height is probed: move this manager's bodies out of the way."""

    def reset(self, ctx: ResetContext) -> None:
        """At reset, once the machine stands at the route's start: start this manager's episode."""

    def before_step(self, ctx: TickContext) -> None:
        """Every step, before the machine's physics substeps."""

    def after_step(self, ctx: TickContext) -> None:
        """Every step, after the machine's physics substeps and before sensing."""

    def view_fields(self) -> dict[str, Any]:
        """`sim.metrics.EpisodeView` fields this manager supplies to the measures (read at reset)."""
        return {}
