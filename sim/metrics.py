"""Episode metrics as small registered measures (habitat-lab style).

A measure is a class with `reset(view)`, `update(view)` (after every step) and `value(view, metrics)` (at
episode end; `metrics` holds the values of the measures computed before it). `view` is an `EpisodeView`: the running
episode's record and the constants measures need, built by the env at reset; a measure never reads the env. It
declares what it needs: `requires` (measures listed before it: SNS reads STL and PSC) and `needs_agents` (an env
with cohabitants). `make_measures` checks both when an env is built, so a wrong list fails at `gymnasium.make`, not at
an episode's end. Register one with `@register_measure("name")`; an env lists the measures it computes in its config
(`measures`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

from kernel.config import ConfigError


def _no_agents() -> float:
    return math.inf


@dataclass(frozen=True)
class EpisodeView:
    """What measures read of one episode: its record and its env's constants, never the env itself."""

    episode: Any  # sim.envs.episode.Episode of the running episode, updated in place every step
    route_length: float  # metres
    dt: float  # seconds a step
    cruise_speed: float  # STL's reference speed: min(config stl_cruise_speed, the machine's v_max)
    collision_kinds: tuple[str, ...]  # every kind the env reports `collisions_<kind>` for
    reference_length: Callable[[], float]  # SPL's geodesic l, planned on first use
    min_agent_distance: Callable[[], float] = _no_agents  # body-surface distance to the nearest agent, this step
    personal_space: float = 0.0  # metres between body surfaces (SocialNav's PSC)


class Measure:
    """Base class: override `reset`, `update` and `value`; declare `requires` and `needs_agents`."""

    name: str = ""
    requires: tuple[str, ...] = ()  # measures that must be listed (and so computed) before this one
    needs_agents: bool = False  # reads the cohabitants (SocialNav)

    def reset(self, view: EpisodeView) -> None:
        """Called at the end of env.reset (the episode's route and machine are set)."""

    def update(self, view: EpisodeView) -> None:
        """Called at the end of every env.step."""

    def value(self, view: EpisodeView, metrics: dict[str, float]) -> dict[str, float]:
        """The measure's value(s) at episode end, as {key: number}."""
        raise NotImplementedError


MEASURES: dict[str, type[Measure]] = {}
M = TypeVar("M", bound=type[Measure])


def register_measure(name: str) -> Callable[[M], M]:
    """Class decorator adding a Measure subclass to the registry under `name`."""

    def deco(cls: M) -> M:
        cls.name = name
        MEASURES[name] = cls
        return cls

    return deco


def make_measures(names: list[str], *, agents: bool = True) -> list[Measure]:
    """Instantiate the named measures in order, checking that each one's needs are met (else ConfigError)."""
    out: list[Measure] = []
    for i, n in enumerate(names):
        if n not in MEASURES:
            raise ConfigError(f"unknown measure {n!r}; registered measures: {', '.join(sorted(MEASURES))}")
        m = MEASURES[n]()
        missing = [r for r in m.requires if r not in names[:i]]
        if missing:
            raise ConfigError(
                f"measure {n!r} needs {', '.join(map(repr, missing))} listed before it in config.measures"
            )
        if m.needs_agents and not agents:
            raise ConfigError(
                f"measure {n!r} needs cohabitants; use curbside/SocialNav-v0 or drop it from config.measures"
            )
        out.append(m)
    return out


class Readout(Measure):
    """A measure read off the finished episode by one function (a row of READOUTS)."""

    read: Callable[[EpisodeView], dict[str, float]]

    def value(self, view: EpisodeView, metrics: dict[str, float]) -> dict[str, float]:
        return self.read(view)


# name -> (what it measures, its values at episode end from the view); each row is registered as a Readout
# subclass of its own, so every measure in MEASURES is a class.
READOUTS: dict[str, tuple[str, Callable[[EpisodeView], dict[str, float]]]] = {
    "success": (
        "1 when the episode completed >= success_completion of the route, else 0",
        lambda v: {"success": float(v.episode.succeeded)},
    ),
    "route_completion": (
        "largest fraction of the reference route reached (0..1)",
        lambda v: {"route_completion": float(min(v.episode.max_progress / v.route_length, 1.0))},
    ),
    "path_length": (
        "planar distance the machine travelled, in metres",
        lambda v: {"path_length": float(v.episode.path_length)},
    ),
    "cost": (
        "steps in contact with a body of the env's `cost_kinds` (the episode's safety cost)",
        lambda v: {"cost": float(v.episode.cost_total)},
    ),
    "time": (
        "simulated episode duration in seconds, and the number of steps",
        lambda v: {"time": float(v.episode.steps * v.dt), "steps": float(v.episode.steps)},
    ),
}
for _name, (_doc, _read) in READOUTS.items():
    register_measure(_name)(type(f"Readout_{_name}", (Readout,), {"__doc__": _doc, "read": staticmethod(_read)}))


@register_measure("spl")
class SPL(Measure):
    """Success weighted by path length: S * l / max(p, l) (Anderson et al. 2018).

    l is the geodesic (the route pulled taut over the cells the machine fits in) from the start to the route
    point where success is declared (`success_completion`, 95 %): the shortest path that earns success.
    p is the path driven until the episode ended. Driving the middle of the path round a corner, weaving or
    detouring all make p > l, so an expert scores below 1 wherever it is not on the shortest path.
    """

    def value(self, view: EpisodeView, metrics: dict[str, float]) -> dict[str, float]:
        if not view.episode.succeeded:
            return {"spl": 0.0}
        l_ref = view.reference_length()
        return {"spl": l_ref / max(view.episode.path_length, l_ref, 1e-9)}


@register_measure("stl")
class SuccessWeightedTimeLength(Measure):
    """S * min(1, t_ref / t), t_ref = l / min(stl_cruise_speed, v_max), l the same geodesic as SPL's (Deitke et al. 2022)."""

    def value(self, view: EpisodeView, metrics: dict[str, float]) -> dict[str, float]:
        if not view.episode.succeeded:
            return {"stl": 0.0}
        t_ref = view.reference_length() / view.cruise_speed
        t = max(view.episode.steps * view.dt, 1e-9)
        return {"stl": min(1.0, t_ref / t)}


@register_measure("collisions")
class Collisions(Measure):
    """Collision steps by kind: `collisions_<kind>` for every kind the env knows, plus `collisions`."""

    def value(self, view: EpisodeView, metrics: dict[str, float]) -> dict[str, float]:
        counts = view.episode.collision_counts
        out = {f"collisions_{k}": float(counts.get(k, 0)) for k in view.collision_kinds}
        out["collisions"] = float(sum(counts.values()))
        return out


@register_measure("psc")
class PersonalSpaceCompliance(Measure):
    """SocialNav: the fraction of steps with every agent's body farther than `personal_space` from the ego's footprint.

    Measured between body surfaces (ego rectangle to agent circle); 0.45 m is the edge of Hall's intimate
    distance (Hall 1966). A threshold between centres smaller than two bodies' radii could never fail.
    """

    needs_agents = True

    def reset(self, view: EpisodeView) -> None:
        self.ok = self.steps = 0

    def update(self, view: EpisodeView) -> None:
        self.steps += 1
        self.ok += int(view.min_agent_distance() > view.personal_space)

    def value(self, view: EpisodeView, metrics: dict[str, float]) -> dict[str, float]:
        return {"psc": self.ok / self.steps if self.steps else 1.0}


@register_measure("sns")
class SocialNavigationScore(Measure):
    """SocialNav: SNS = mean(STL, PSC) (Deitke et al. 2022)."""

    requires = ("stl", "psc")

    def value(self, view: EpisodeView, metrics: dict[str, float]) -> dict[str, float]:
        return {"sns": 0.5 * (metrics["stl"] + metrics["psc"])}


POINTNAV_MEASURES = ["success", "spl", "route_completion", "cost", "collisions", "path_length", "time"]
SOCIALNAV_MEASURES = [*POINTNAV_MEASURES, "psc", "stl", "sns"]
