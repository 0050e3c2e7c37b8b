"""The batched training env cut into shards (curbside.train.batched_shards) against one batched env of all the envs:
real BatchedPointNav / BatchedSocialNav shards, the others in forkserver worker processes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from curbside.train.batched_shards import BatchedShards
from curbside.train.envs import BatchedShard, split_config

CFG = {"lidar": {"beams": 24, "low_beams": 8}, "route_length": [5.0, 25.0], "scene": {"blocks": 1}, "horizon": 40}


def _roll(vec, steps: int, seed: int = 3) -> list:
    vec.seed(seed)
    trace = [vec.reset()]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        vec.step_async(rng.uniform(-1.0, 1.0, (vec.num_envs, 2)).astype(np.float32))
        obs, rewards, dones, infos = vec.step_wait()
        ends = [(i, info["terminal_observation"], info.get("is_success")) for i, info in enumerate(infos) if dones[i]]
        trace += [obs, rewards, dones, ends]
    return trace


def _same(a: list, b: list) -> bool:
    for x, y in zip(a, b, strict=True):
        if isinstance(x, list):
            if len(x) != len(y) or any(
                i != j or s != t or not np.array_equal(o, p) for (i, o, s), (j, p, t) in zip(x, y)
            ):
                return False
        elif not np.array_equal(x, y):
            return False
    return True


@pytest.mark.parametrize("task", ["PointNav", "SocialNav"])
def test_shards_step_each_env_as_one_batched_env_does(task) -> None:
    # Routes planned at every reset (no route pool shared among a shard's envs), so env i draws the same scenes,
    # routes and episodes whichever shard steps it: the sharded env's observations, rewards, dones and final
    # observations equal one batched env's, step for step, across episode ends.
    cfg = {**split_config(CFG, "train", 4), "route_pool": 0}
    make = BatchedShard(task, cfg)
    one = make(5)
    sharded = BatchedShards(make, 5, 2)
    try:
        assert sharded.bounds == [(0, 2), (2, 5)]
        a, b = _roll(one, 60), _roll(sharded, 60)
        assert any(len(x) for x in a[4::4])  # episodes ended (40-step horizon) and the envs reset themselves
        assert _same(a, b)
        assert sharded.get_attr("num_envs") == [2, 2, 3, 3, 3]  # each env answers with its own shard's attribute
        assert sharded.env_is_wrapped(object) == [False] * 5
    finally:
        one.close()
        sharded.close()
    assert not any(p.is_alive() for p in sharded.procs)


@dataclass(frozen=True)
class _FailsOnThree:
    """A shard builder whose 3-env shard (the worker's, of 5 envs in 2 shards) has a bad LiDAR config."""

    def __call__(self, n: int):
        lidar = {"beams": -3 if n == 3 else 24, "low_beams": 8}
        return BatchedShard("PointNav", {**split_config(CFG, "train", 2), "lidar": lidar})(n)


def test_a_shard_that_fails_in_its_worker_raises_its_error() -> None:
    with pytest.raises(RuntimeError, match="(?s)shard 1 failed in its worker process.*lidar.beams must be"):
        BatchedShards(_FailsOnThree(), 5, 2)


def test_a_worker_that_dies_fails_the_next_step_clearly() -> None:
    sharded = BatchedShards(BatchedShard("PointNav", split_config(CFG, "train", 2)), 2, 2)
    sharded.reset()
    sharded.procs[0].kill()
    sharded.procs[0].join()
    sharded.step_async(np.zeros((2, 2), dtype=np.float32))
    with pytest.raises(RuntimeError, match="shard 1's worker process died"):
        sharded.step_wait()
    assert sharded.closed


def test_training_shards_socialnav_over_the_cores_and_keeps_pointnav_in_one_process() -> None:
    from curbside.train.envs import make_training_vec
    from curbside.train.sharded import usable_cores
    from curbside.train.vec import VectorEnvAdapter

    cores = usable_cores()
    for task, want in (("PointNav", 1), ("SocialNav", min(cores, 4))):
        vec = make_training_vec(task, CFG, 4, 2, backend="batched")
        try:
            inner = vec.venv
            got = len(inner.bounds) if isinstance(inner, BatchedShards) else 1
            assert got == want, task
            assert isinstance(inner, BatchedShards if want > 1 else VectorEnvAdapter), task
        finally:
            vec.close()
    one = make_training_vec("SocialNav", CFG, 4, 2, backend="batched", subprocess=False)
    assert isinstance(one.venv, VectorEnvAdapter)
    one.close()
