"""Episode metrics as small registered measures (habitat-lab style).

A measure is a class with `reset(env)`, `update(env)` (after every step) and `value(env, metrics)`
(at episode end; `metrics` holds the values of the measures computed before it, so SNS can read STL and
PSC). Register one with `@register_measure("name")`; an env lists the measures it computes in its
config (`measures`). The env attributes the PointNav measures read are documented in docs/simulator.md.
"""

from __future__ import annotations

from typing import Any, Callable, TypeVar

from curbside.config import ConfigError


class Measure:
    """Base class: override `reset`, `update` and `value`."""

    name: str = ""

    def reset(self, env: Any) -> None:
        """Called at the end of env.reset (the episode's route and machine are set)."""

    def update(self, env: Any) -> None:
        """Called at the end of every env.step."""

    def value(self, env: Any, metrics: dict[str, float]) -> dict[str, float]:
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


def make_measures(names: list[str]) -> list[Measure]:
    """Instantiate the named measures in order; unknown names raise listing the registered ones."""
    out = []
    for n in names:
        if n not in MEASURES:
            raise ConfigError(f"unknown measure {n!r}; registered measures: {', '.join(sorted(MEASURES))}")
        out.append(MEASURES[n]())
    return out


@register_measure("success")
class Success(Measure):
    """1 when the episode completed >= success_completion of the route, else 0."""

    def value(self, env: Any, metrics: dict[str, float]) -> dict[str, float]:
        return {"success": float(env.episode.succeeded)}


@register_measure("route_completion")
class RouteCompletion(Measure):
    """Largest fraction of the reference route reached (0..1)."""

    def value(self, env: Any, metrics: dict[str, float]) -> dict[str, float]:
        return {"route_completion": float(min(env.episode.max_progress / env.route.length, 1.0))}


@register_measure("path_length")
class PathLength(Measure):
    """Planar distance the machine travelled, in metres."""

    def value(self, env: Any, metrics: dict[str, float]) -> dict[str, float]:
        return {"path_length": float(env.episode.path_length)}


@register_measure("spl")
class SPL(Measure):
    """Success weighted by path length: S * l / max(p, l) (Anderson et al. 2018).

    l is the geodesic (the route pulled taut over the cells the machine fits in) from the start to the route
    point where success is declared (`success_completion`, 95 %): the shortest path that earns success.
    p is the path driven until the episode ended. Driving the middle of the path round a corner, weaving or
    detouring all make p > l, so an expert scores below 1 wherever it is not on the shortest path.
    """

    def value(self, env: Any, metrics: dict[str, float]) -> dict[str, float]:
        if not env.episode.succeeded:
            return {"spl": 0.0}
        l_ref = env.reference_length()
        return {"spl": l_ref / max(env.episode.path_length, l_ref, 1e-9)}


@register_measure("stl")
class SuccessWeightedTimeLength(Measure):
    """S * min(1, t_ref / t), t_ref = l / min(stl_cruise_speed, v_max), l the same geodesic as SPL's (Deitke et al. 2022)."""

    def value(self, env: Any, metrics: dict[str, float]) -> dict[str, float]:
        if not env.episode.succeeded:
            return {"stl": 0.0}
        v = min(float(env.config.get("stl_cruise_speed", 2.5)), env.machine.spec.v_max)
        t_ref = env.reference_length() / v
        t = max(env.episode.steps * env.dt, 1e-9)
        return {"stl": min(1.0, t_ref / t)}


@register_measure("cost")
class Cost(Measure):
    """Steps in contact with a body of the env's `cost_kinds` (the episode's safety cost)."""

    def value(self, env: Any, metrics: dict[str, float]) -> dict[str, float]:
        return {"cost": float(env.episode.cost_total)}


@register_measure("collisions")
class Collisions(Measure):
    """Collision steps by kind: `collisions_<kind>` for every kind the env knows, plus `collisions`."""

    def value(self, env: Any, metrics: dict[str, float]) -> dict[str, float]:
        out = {f"collisions_{k}": float(env.episode.collision_counts.get(k, 0)) for k in env.collision_kinds_all}
        out["collisions"] = float(sum(env.episode.collision_counts.values()))
        return out


@register_measure("time")
class Time(Measure):
    """Simulated episode duration in seconds, and the number of steps."""

    def value(self, env: Any, metrics: dict[str, float]) -> dict[str, float]:
        return {"time": float(env.episode.steps * env.dt), "steps": float(env.episode.steps)}


POINTNAV_MEASURES = ["success", "spl", "route_completion", "cost", "collisions", "path_length", "time"]
