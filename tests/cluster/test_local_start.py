"""`--executor ray` without a cluster starts one for the run (workers at the command's priority) and stops it."""

from __future__ import annotations

import os

import pytest


def niceness(item: int) -> tuple[int, int]:
    """(item, this worker process's niceness)."""
    return item, os.nice(0)


def test_run_map_starts_a_local_cluster_and_stops_it() -> None:
    ray = pytest.importorskip("ray")
    from curbside.executors import run_map

    assert not ray.is_initialized()
    nodes: dict[str, int] = {}
    out = list(run_map(niceness, range(6), executor="ray", workers=2, nodes=nodes))
    assert [i for i, _ in out] == list(range(6)) and sum(nodes.values()) == 6
    # Ray would run its workers at +15; ours run at the driver's priority, as the process pool's do.
    assert {n for _, n in out} == {os.nice(0)}
    assert not ray.is_initialized()
