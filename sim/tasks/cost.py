"""A step's safety cost, written once over numbers or arrays: `CostRule` decides it for the PyBullet env's one
episode and the batched env's n.

Two rules (`cost_rule` in a task config):

| rule | a step costs 1 when the machine |
|---|---|
| `contact_steps` | touches a body of a `cost_kinds` kind (every step in contact) |
| `metaurban` | leaves the route (lateral offset past `out_of_route_distance`), touches a moving cost kind (agent, vehicle), or touches a static cost-kind body (an object) it has not touched before in the episode |

`metaurban` is MetaUrban's `cost_function` (metaurban/envs/sidewalk_static_env.py at commit 6b8ff9a: out of road,
else a vehicle crash, else an object crash, each `crash_*_cost` 1 by default) with its collision callback
(metaurban/engine/core/collision_callback.py): a street object (`TrafficObject`, COST_ONCE) raises the ego's
`crash_object` flag at its first contact only, a vehicle at every contact, and no building is charged.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from kernel.config import ConfigError

COST_RULES = ("contact_steps", "metaurban")
STATIC_KINDS = ("object", "building", "curb")  # bodies that stay where they are: charged once under `metaurban`
MOVING_KINDS = ("agent", "vehicle")
# What MetaUrban's cost function charges: objects once, agents and vehicles every step; buildings and curbs never.
METAURBAN_KINDS = ("object", "agent", "vehicle")


@dataclass(frozen=True)
class CostRule:
    """One task config's cost rule (see the module docstring)."""

    rule: str
    out_of_route_distance: float

    @property
    def once(self) -> bool:
        """Whether a static body is charged at its first contact only (the env remembers the bodies charged)."""
        return self.rule == "metaurban"

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any]) -> CostRule:
        """The rule of a task config; a `metaurban` rule with a cost kind MetaUrban never charges raises."""
        rule = str(cfg["cost_rule"])
        if rule == "metaurban":
            extra = sorted(set(cfg["cost_kinds"]) - set(METAURBAN_KINDS))
            if extra:
                raise ConfigError(
                    f"config.cost_kinds {extra} are never charged by MetaUrban's cost function (cost_rule "
                    f"'metaurban'); use cost kinds from {', '.join(METAURBAN_KINDS)}, or cost_rule 'contact_steps'"
                )
        return cls(rule, float(cfg["out_of_route_distance"]))

    def __call__(self, in_cost_contact: Any, new_static: Any, moving: Any, lateral: Any) -> Any:
        """The step's cost (True/1 or False/0; numbers or arrays): `in_cost_contact`, a body of a cost kind touched;
        `new_static`, a static cost-kind body touched for the first time in the episode; `moving`, an agent or
        vehicle of a cost kind touched; `lateral`, the offset from the route."""
        if self.rule == "contact_steps":
            return in_cost_contact
        return new_static | moving | (abs(lateral) > self.out_of_route_distance)
