"""A Ray worker killed mid-run: Ray retries its task, and the output holds every scene and episode exactly once,
equal to a local run (the test starts its own 2-CPU cluster and SIGKILLs one worker process it finds running)."""

from __future__ import annotations

import json
import os
import signal
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.cluster.conftest import tree_bytes

psutil = pytest.importorskip("psutil")


def killer(task_name: str, killed: list[int]) -> Callable[[int], None]:
    """A progress callback that, at the first finished item, SIGKILLs one Ray worker running `task_name`."""

    def on_progress(n: int) -> None:
        if killed:
            return
        for proc in psutil.Process().children(recursive=True):  # this test's own cluster only
            try:
                title = " ".join(proc.cmdline())
            except psutil.Error:
                continue
            if title.startswith(f"ray::{task_name}"):  # Ray titles a busy worker with the task it runs
                os.kill(proc.pid, signal.SIGKILL)
                killed.append(proc.pid)
                return

    return on_progress


def test_a_killed_scene_worker_is_retried_and_nothing_is_lost_or_doubled(ray_local, tmp_path: Path) -> None:
    from sim.scene.dataset import build_dataset

    local = build_dataset("train", 10, tmp_path / "local", base={"blocks": 1}, executor="local")
    killed: list[int] = []
    rows = build_dataset(
        "train",
        10,
        tmp_path / "ray",
        base={"blocks": 1},
        executor="ray",
        workers=2,
        progress=killer("scene_item", killed),
    )
    assert len(killed) == 1, "no busy worker was found to kill"
    assert not psutil.pid_exists(killed[0]) or psutil.Process(killed[0]).status() == psutil.STATUS_ZOMBIE
    assert [r["seed"] for r in rows] == list(range(10))  # each scene once, in order
    assert sorted(p.name for p in (tmp_path / "ray" / "scenes").iterdir()) == [f"train_{k:08d}.json" for k in range(10)]
    assert rows == local
    assert tree_bytes(tmp_path / "ray") == tree_bytes(tmp_path / "local")


def test_a_killed_eval_worker_is_retried_and_the_metrics_equal_a_local_run(ray_local) -> None:
    from sim.eval import evaluate

    cfg = {"scene": {"blocks": 1}, "horizon": 200}
    local = evaluate("curbside/PointNav-v0", "expert", 8, cfg, seed=0)
    killed: list[int] = []
    from kernel.executors import run_map
    from sim.eval import episode_metrics, summarize

    job = ("curbside/PointNav-v0", "expert", cfg)
    rows = list(
        run_map(
            episode_metrics,
            range(8),
            executor="ray",
            workers=2,
            args=(job,),
            progress=killer("episode_metrics", killed),
        )
    )
    assert len(killed) == 1, "no busy worker was found to kill"
    assert len(rows) == 8 and rows == local["per_episode"]
    assert json.dumps(summarize(rows), sort_keys=True) == json.dumps(summarize(local["per_episode"]), sort_keys=True)
