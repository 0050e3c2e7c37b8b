"""The env's managers: every hook called in its place, in list order, with explicit inputs, per cached world."""

from __future__ import annotations

from typing import Any

import numpy as np

from sim.envs.managers import Manager, ResetContext, SceneContext, TickContext
from sim.envs.pointnav import PointNavEnv


class Recorder(Manager[str]):
    """Logs every hook it gets; its per-world state is the name of the world it was made in."""

    def __init__(self, name: str, log: list[tuple[str, ...]]) -> None:
        self.name, self.log = name, log
        self.world: str | None = None
        self.made = 0  # worlds built so far

    def on_scene(self, ctx: SceneContext) -> None:
        assert ctx.collision_kinds == {} and ctx.lidars
        self.world = f"world{self.made}"
        self.made += 1
        self.log.append((self.name, "on_scene", self.world))

    def leave_scene(self) -> str | None:
        self.log.append((self.name, "leave_scene", str(self.world)))
        return self.world

    def enter_scene(self, state: str | None) -> None:
        self.world = state
        self.log.append((self.name, "enter_scene", str(state)))

    def park(self) -> None:
        self.log.append((self.name, "park"))

    def reset(self, ctx: ResetContext) -> None:
        assert isinstance(ctx.rng, np.random.Generator) and ctx.route.length > 0
        self.log.append((self.name, "reset"))

    def before_step(self, ctx: TickContext) -> None:
        self.log.append((self.name, "before_step", str(ctx.action)))

    def after_step(self, ctx: TickContext) -> None:
        self.log.append((self.name, "after_step"))

    def view_fields(self) -> dict[str, Any]:
        return {"personal_space": 0.5} if self.name == "b" else {}


def test_hooks_run_in_order_per_world() -> None:
    env = PointNavEnv({"num_scenes": 2, "scene_cache": 2})
    log: list[tuple[str, ...]] = []
    env.managers = [Recorder("a", log), Recorder("b", log)]
    keys = []
    returns = 0
    for seed in range(8):
        log.clear()
        env.reset(seed=seed)
        first = env.slot.key not in keys
        back = not first and keys[-1] != env.slot.key
        keys.append(env.slot.key)
        names = [e[1] for e in log if e[0] == "a"]
        assert [e[0] for e in log] == ["a", "b"] * (len(log) // 2)  # each hook: a, then b
        want = (["leave_scene"] if len(keys) > 1 and keys[-2] != keys[-1] else []) + (
            ["on_scene"] if first else ["enter_scene"] if back else []
        )
        assert names == [*want, "park", "reset"]
        assert env.measure_view.personal_space == 0.5
        if back:  # the world comes back with the state it was left with
            returns += 1
            world = next(e[2] for e in log if e[1] == "enter_scene")
            assert world == f"world{sorted(set(keys), key=keys.index).index(env.slot.key)}"
    assert len(set(keys)) == 2 and returns > 0
    log.clear()
    env.step([0.5, 1.0])
    assert log == [
        ("a", "before_step", "(0.5, 1.0)"),
        ("b", "before_step", "(0.5, 1.0)"),
        ("a", "after_step"),
        ("b", "after_step"),
    ]
    env.close()
