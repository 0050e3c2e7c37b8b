"""`--executor ray` without a cluster starts one for the run (workers at the command's priority) and stops it."""

from __future__ import annotations

import os

import pytest


def niceness(item: int) -> tuple[int, int]:
    """(item, this worker process's niceness)."""
    return item, os.nice(0)


def test_run_map_starts_a_local_cluster_and_stops_it() -> None:
    ray = pytest.importorskip("ray")
    from kernel.executors import run_map

    assert not ray.is_initialized()
    nodes: dict[str, int] = {}
    out = list(run_map(niceness, range(6), executor="ray", workers=2, nodes=nodes))
    assert [i for i, _ in out] == list(range(6)) and sum(nodes.values()) == 6
    # Ray would run its workers at +15; ours run at the driver's priority, as the process pool's do.
    assert {n for _, n in out} == {os.nice(0)}
    assert not ray.is_initialized()


def test_two_tasks_a_cpu_stay_in_flight_on_a_cluster_sized_by_workers() -> None:
    from kernel.executors import in_flight

    # A lone worker gets its next task queued while the driver collects the last one (the local cluster has
    # exactly `workers` CPUs, so Ray still runs one at a time); on a bigger cluster `workers` caps the tasks.
    assert in_flight(1, 1) == 2 and in_flight(2, 2) == 4 and in_flight(None, 8) == 16
    assert in_flight(4, 64) == 4
    # A cluster reporting less than one CPU: 0 in flight made the ray map return no results at all.
    assert in_flight(None, 0) == 2 and in_flight(2, 0) == 2
