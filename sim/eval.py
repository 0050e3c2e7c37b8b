"""Policy evaluation over episodes: SR, SPL, Cost and the mean of every other numeric metric the env reports."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from sim.rollout import make_policy, rollout


def evaluate(
    env_id: str,
    policy: str,
    episodes: int,
    config: Mapping[str, Any] | None = None,
    *,
    seed: int = 0,
    progress: bool = False,
    executor: str = "local",
    workers: int | None = None,
    address: str | None = None,
    nodes: dict[str, int] | None = None,
) -> dict[str, Any]:
    """Mean metrics over `episodes` episodes with seeds seed..seed+N-1: keys sr, spl, cost, episodes, ...

    `executor` (kernel.executors: local, process or ray at `address`) shards the episodes over workers; each
    episode depends on its seed alone and the rows are aggregated in seed order, so every executor gives the
    same summary, byte for byte. `nodes`, when given, receives the episodes each (Ray) node ran.
    """
    from kernel.executors import run_map

    job = (env_id, policy, dict(config or {}))
    rows: list[dict[str, Any]] = []
    bar = None
    if progress:
        from rich.progress import Progress

        bar = Progress(transient=True)
        task = bar.add_task(f"{env_id} {policy}", total=episodes)
        bar.start()
    try:
        advance = (lambda n: bar.advance(task, n)) if bar is not None else None
        rows.extend(
            run_map(
                episode_metrics,
                range(seed, seed + episodes),
                executor=executor,
                workers=workers,
                address=address,
                args=(job,),
                progress=advance,
                nodes=nodes,
            )
        )
    finally:
        if bar is not None:
            bar.stop()
    summary = summarize(rows)
    summary["seed"] = seed
    summary["per_episode"] = rows
    return summary


def episode_metrics(seed: int, job: tuple[str, str, dict[str, Any]]) -> dict[str, Any]:
    """The metrics of one episode (`job`: env id, policy name, env config) in this worker's env, built once per
    process: an episode depends on its seed alone (reset and the action space are seeded with it)."""
    import json

    from kernel.executors import worker_state

    env_id, policy, config = job

    def build() -> _EnvPolicy:
        import gymnasium as gym

        from sim.envs import register_envs

        register_envs()
        env = gym.make(env_id, config=dict(config))
        return _EnvPolicy(env, make_policy(policy, env))

    held = worker_state("eval_env", json.dumps(job, sort_keys=True, default=str), build)
    return rollout(held.env, held.act, seed)


class _EnvPolicy:
    """An env and its policy, closed together when a worker's slot is reused or released."""

    def __init__(self, env: Any, act: Any) -> None:
        self.env, self.act = env, act

    def close(self) -> None:
        """Close the env."""
        self.env.close()


def summarize(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean of every numeric metric over episodes; `success` becomes `sr`; `episodes` is the count."""
    keys = sorted({k for r in rows for k, v in r.items() if isinstance(v, (int, float))})
    summary: dict[str, Any] = {k: float(np.mean([r.get(k, 0.0) for r in rows])) for k in keys}
    summary["sr"] = summary.pop("success")
    summary["episodes"] = len(rows)
    return summary


def write_eval(summary: dict[str, Any], out: str | Path) -> tuple[Path, Path]:
    """Write `summary` as out/metrics.json (sorted keys, without the per-episode rows) and its rows as
    out/episodes.csv (one row per episode in seed order, columns sorted): the files a sharded run is compared by."""
    import csv
    import io
    import json

    from sim.scene.spec import write_atomic

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows = summary.get("per_episode", [])
    head = {k: v for k, v in summary.items() if k != "per_episode"}
    write_atomic(out / "metrics.json", json.dumps(head, indent=2, sort_keys=True) + "\n", durable=False)
    buf = io.StringIO()
    cols = sorted({k for r in rows for k in r})
    writer = csv.DictWriter(buf, fieldnames=["seed", *cols], lineterminator="\n")
    writer.writeheader()
    first = int(summary.get("seed", 0))
    for k, r in enumerate(rows):
        writer.writerow(
            {"seed": first + k, **{c: repr(r[c]) if isinstance(r.get(c), float) else r.get(c, "") for c in cols}}
        )
    write_atomic(out / "episodes.csv", buf.getvalue(), durable=False)
    return out / "metrics.json", out / "episodes.csv"
