"""A simulated multi-node cluster (ray.cluster_utils.Cluster: one raylet per node on this machine): items spread over
the nodes and the aggregated output equals a local run's."""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.cluster.conftest import tree_bytes

NODES = 3  # the benchmark runs 8 (benchmarks/ray_scaling.py); 3 keeps the suite fast on 2 cores


@pytest.fixture(scope="module")
def cluster() -> Iterator[str]:
    """NODES one-CPU nodes, the driver connected to the head; yields the cluster address."""
    pytest.importorskip("ray")
    import ray
    from ray.cluster_utils import Cluster

    os.environ.setdefault("RAY_AUTH_MODE", "disabled")
    c = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    for _ in range(NODES - 1):
        c.add_node(num_cpus=1)
    c.wait_for_nodes()
    ray.init(address=c.address, log_to_driver=False)
    _warm_every_node(ray)
    try:
        yield c.address
    finally:
        ray.shutdown()
        c.shutdown()


def _warm_every_node(ray: Any) -> None:
    """Run one task pinned to each node, so every node has a worker and the scheduler's view holds all three.

    wait_for_nodes returns once the nodes are registered, which can come before their resources reach the
    scheduler: on a fast machine the scenes then all ran on the head (8 of 8), and the spread check failed on a
    cluster that was still forming rather than on the executor."""
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    @ray.remote(num_cpus=1)
    def node_id() -> str:
        return str(ray.get_runtime_context().get_node_id())

    alive = [n["NodeID"] for n in ray.nodes() if n["Alive"]]
    assert len(alive) == NODES, ray.nodes()
    pinned = [
        node_id.options(scheduling_strategy=NodeAffinitySchedulingStrategy(n, soft=False)).remote() for n in alive
    ]
    assert sorted(ray.get(pinned, timeout=120)) == sorted(alive)


def test_scenes_spread_over_the_nodes_and_equal_a_local_run(cluster: str, tmp_path: Path) -> None:
    from sim.scene.dataset import build_dataset

    build_dataset("unseen", 8, tmp_path / "local", base={"blocks": 1}, executor="local")
    nodes: dict[str, int] = {}
    build_dataset("unseen", 8, tmp_path / "ray", base={"blocks": 1}, executor="ray", nodes=nodes)
    assert len(nodes) >= 2 and sum(nodes.values()) == 8, nodes  # the scenes ran on several nodes
    assert tree_bytes(tmp_path / "ray") == tree_bytes(tmp_path / "local")


def test_eval_on_the_nodes_aggregates_like_a_local_run(cluster: str) -> None:
    from sim.eval import evaluate

    cfg = {"scene": {"blocks": 1}, "horizon": 150}
    local = evaluate("curbside/SocialNav-v0", "random", 6, cfg, seed=11)
    nodes: dict[str, int] = {}
    sharded = evaluate("curbside/SocialNav-v0", "random", 6, cfg, seed=11, executor="ray", nodes=nodes)
    assert sum(nodes.values()) == 6 and all(k != "local" for k in nodes)
    assert json.dumps(sharded, sort_keys=True) == json.dumps(local, sort_keys=True)
