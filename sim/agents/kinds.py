"""The table of cohabitant kinds: body size, speeds, colour and daily movements, with the source of each value.

The values live in `kinds.csv`: rounded engineering choices anchored on the references in `source`; docs/agents.md explains them.
Radii are those of the circle ORCA uses (the body's half-width plus a little room for swinging arms,
pedals or a board), not the circumscribed circle of the whole vehicle, so that two agents can pass on a
2.4 m clear path as they do in reality.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from importlib import resources

import numpy as np

MOVEMENTS: tuple[str, ...] = ("idle", "walking", "running")
IDLE, WALKING, RUNNING = range(len(MOVEMENTS))  # an agent's `movement` code is its index in MOVEMENTS


@dataclass(frozen=True)
class AgentKind:
    """One kind of cohabitant: ORCA radius (m), preferred speed and its spread (m/s), body and colour."""

    name: str
    radius: float
    pref_speed: float
    speed_std: float
    run_speed: float | None  # None: this kind never runs (machines, wheeled users keep one cruise speed)
    height: float
    color: tuple[float, float, float]
    source: str

    def sample_speed(self, rng: np.random.Generator, movement: str) -> float:
        """Draw a preferred speed for `movement`, clipped to a plausible band around the kind's mean."""
        if movement == "idle":
            return 0.0
        mean = self.run_speed if movement == "running" and self.run_speed else self.pref_speed
        lo, hi = 0.5 * mean, mean + 2.0 * self.speed_std
        return float(np.clip(rng.normal(mean, self.speed_std), lo, hi))


def _rgb(text: str) -> tuple[float, float, float]:
    """The colour column's "r g b" as three floats (ValueError for any other count)."""
    r, g, b = (float(c) for c in text.split())
    return r, g, b


def _load_kinds() -> tuple[dict[str, AgentKind], dict[str, float]]:
    """The kinds table `kinds.csv` beside this module (row order is the kind index) and each kind's spawn share."""
    with resources.files("sim.agents").joinpath("kinds.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    kinds = {
        r["name"]: AgentKind(
            r["name"],
            float(r["radius"]),
            float(r["pref_speed"]),
            float(r["speed_std"]),
            float(r["run_speed"]) if r["run_speed"] else None,
            float(r["height"]),
            _rgb(r["color"]),
            r["source"],
        )
        for r in rows
    }
    return kinds, {r["name"]: float(r["mix"]) for r in rows}


# Share of each kind when spawning by density (the `mix` column): pedestrians dominate real sidewalks.
AGENT_KINDS, DEFAULT_MIX = _load_kinds()
KIND_NAMES: tuple[str, ...] = tuple(AGENT_KINDS)
KIND_INDEX: dict[str, int] = {n: i for i, n in enumerate(KIND_NAMES)}


def agent_kind(name: str) -> AgentKind:
    """Return the kind called `name`, or raise naming the valid kinds."""
    try:
        return AGENT_KINDS[name]
    except KeyError:
        raise ValueError(f"unknown agent kind {name!r}; valid kinds: {', '.join(KIND_NAMES)}") from None
