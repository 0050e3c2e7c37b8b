"""One step's PointNav reward in Python floats: `Reward.batch`'s arithmetic (the same IEEE doubles, in the same
order) without a dozen numpy calls on scalars, for the env's every step (tests/sim/agents/test_socialnav_golden.py
checks it against `batch` bit for bit)."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover - typing only; sim.tasks.pointnav imports this module
    from sim.tasks.pointnav import Reward


def step_reward(w: Reward, progress: float, new_progress: float, lateral: float, d_steer: float, speed: float,
                collided: bool, succeeded: bool, out_of_route: bool, stuck: bool) -> float:
    """`w.batch(...)` for one step, as a float."""
    disp = new_progress if w.progress == "max" else progress
    over = abs(lateral) - w.lateral_free
    r = w.disp * disp - w.lateral * max(0.0, over) - w.steering * abs(d_steer) * abs(speed)
    if collided:
        r = r - w.crash
    if w.floor and 0.0 > r:
        r = 0.0
    if succeeded or out_of_route or stuck:
        r = r + (w.success if succeeded else w.out_of_route if out_of_route else w.stuck)
    return float(r)
