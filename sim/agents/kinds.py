"""The table of cohabitant kinds: body size, speeds, colour and daily movements, with the source of each value.

Values are rounded engineering choices anchored on the references in `source`; docs/agents.md explains them.
Radii are those of the circle ORCA uses (the body's half-width plus a little room for swinging arms,
pedals or a board), not the circumscribed circle of the whole vehicle, so that two agents can pass on a
2.4 m clear path as they do in reality.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MOVEMENTS: tuple[str, ...] = ("idle", "walking", "running")


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


AGENT_KINDS: dict[str, AgentKind] = {
    k.name: k
    for k in (
        AgentKind(
            "pedestrian", 0.30, 1.34, 0.26, 3.0, 1.75, (0.20, 0.45, 0.85),
            "Weidmann 1993 (mean free walking speed 1.34 m/s, sd ~0.26); Fruin 1971 body ellipse "
            "0.46 x 0.61 m; jogging ~3 m/s",
        ),
        AgentKind(
            "wheelchair_user", 0.40, 1.0, 0.15, None, 1.30, (0.95, 0.60, 0.10),
            "ADA 2010 Standards 305.3 clear floor space 0.76 x 1.22 m; manual wheelchair community "
            "speeds ~0.8-1.2 m/s",
        ),
        AgentKind(
            "cyclist", 0.45, 3.5, 0.7, None, 1.70, (0.10, 0.65, 0.25),
            "handlebar width ~0.6 m; shared-path cycling 12-15 km/h (AASHTO Guide for the Development of "
            "Bicycle Facilities); slowed on sidewalks",
        ),
        AgentKind(
            "skateboarder", 0.35, 2.8, 0.6, None, 1.75, (0.60, 0.25, 0.75),
            "skateboard commuting ~10 km/h (Fang & Handy 2017, Transportation Research Part D)",
        ),
        AgentKind(
            "scooter_rider", 0.35, 3.5, 0.7, None, 1.80, (0.85, 0.15, 0.15),
            "shared e-scooters: city caps 15-25 km/h, observed means ~12-15 km/h; deck width ~0.5 m",
        ),
        AgentKind(
            "delivery_robot", 0.35, 1.6, 0.1, None, 0.75, (0.95, 0.90, 0.20),
            "Starship-class sidewalk robot: ~0.70 x 0.57 m body, top speed 6 km/h (1.67 m/s)",
        ),
        AgentKind(
            "robot_dog", 0.35, 1.2, 0.2, None, 0.70, (0.35, 0.35, 0.35),
            "Boston Dynamics Spot: 1.1 x 0.5 m body, max 1.6 m/s; Unitree Go1 walking ~1.5 m/s",
        ),
    )
}

KIND_NAMES: tuple[str, ...] = tuple(AGENT_KINDS)
KIND_INDEX: dict[str, int] = {n: i for i, n in enumerate(KIND_NAMES)}

# Share of each kind when spawning by density; pedestrians dominate real sidewalks.
DEFAULT_MIX: dict[str, float] = {
    "pedestrian": 0.60,
    "wheelchair_user": 0.06,
    "cyclist": 0.08,
    "skateboarder": 0.06,
    "scooter_rider": 0.08,
    "delivery_robot": 0.07,
    "robot_dog": 0.05,
}


def agent_kind(name: str) -> AgentKind:
    """Return the kind called `name`, or raise naming the valid kinds."""
    try:
        return AGENT_KINDS[name]
    except KeyError:
        raise ValueError(f"unknown agent kind {name!r}; valid kinds: {', '.join(KIND_NAMES)}") from None
