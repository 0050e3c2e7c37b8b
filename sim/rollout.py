"""The one episode loop: reset with a seed, step a policy to the episode's end, hand each step to a callback."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

Policy = Callable[[Any, np.ndarray], np.ndarray]  # (env, observation) -> action


def make_policy(name: str, env: Any) -> Policy:
    """A callable (env, obs) -> action for `expert` (pure pursuit) or `random` (seeded by the env)."""
    if name == "expert":
        from sim.expert import PurePursuitExpert

        experts: dict[str, PurePursuitExpert] = {}  # one per machine (`PurePursuitExpert.for_machine`)

        def drive(e: Any, obs: Any) -> Any:
            spec = e.unwrapped.spec_machine
            if spec.name not in experts:
                experts[spec.name] = PurePursuitExpert.for_machine(spec)
            return experts[spec.name].act(e)

        return drive
    if name == "random":
        return lambda e, obs: e.action_space.sample()
    raise ValueError(f"unknown policy {name!r}; valid: expert, random")


def rollout(
    env: Any,
    policy: Policy,
    seed: int,
    *,
    on_reset: Callable[[Any], None] | None = None,
    on_step: Callable[[Any, bool], None] | None = None,
) -> dict[str, float]:
    """Run one episode from reset(seed) to its end and return its metrics (the final info's `metrics`).

    The action space is seeded with `seed` too, so a random policy repeats. `on_reset(env)` runs after the
    reset, `on_step(env, done)` after every step (renderers draw frames there).
    """
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    if on_reset is not None:
        on_reset(env)
    while True:
        obs, _, term, trunc, info = env.step(policy(env, obs))
        if on_step is not None:
            on_step(env, term or trunc)
        if term or trunc:
            return dict(info["metrics"])
