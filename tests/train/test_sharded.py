"""ShardedVectorEnv steps exactly as Gymnasium's SyncVectorEnv does (same-step autoreset), with k envs a worker."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

from curbside.train.envs import env_fns
from curbside.train.sharded import ShardedVectorEnv
from curbside.train.vec import VectorEnvAdapter, unbatch

CFG = {"lidar": {"beams": 24, "low_beams": 8}, "route_length": [5.0, 12.0], "scene": {"blocks": 1}, "horizon": 40}


def _equal(a: object, b: object) -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys()
        for k in a:
            _equal(a[k], b[k])
    else:
        np.testing.assert_array_equal(a, b)


def test_sharded_steps_like_sync_vector_env() -> None:
    fns = env_fns("PointNav", CFG, 4, 4)
    ours = ShardedVectorEnv(fns, workers=2)
    ref = SyncVectorEnv(fns, autoreset_mode=AutoresetMode.SAME_STEP)
    try:
        o1, i1 = ours.reset(seed=5)
        o2, i2 = ref.reset(seed=5)
        np.testing.assert_array_equal(o1, o2)
        for ia, ib in zip(unbatch(i1, 4), unbatch(i2, 4)):
            _equal(ia, ib)
        rng = np.random.default_rng(0)
        ended = 0
        for _ in range(100):
            action = rng.uniform(-1, 1, size=(4, 2)).astype(np.float32)
            a, b = ours.step(action), ref.step(action)
            for x, y in zip(a[:4], b[:4]):
                np.testing.assert_array_equal(x, y)
            ended += int(a[2].sum() + a[3].sum())
            for ia, ib in zip(unbatch(a[4], 4), unbatch(b[4], 4)):
                for info in (ia, ib):
                    info.get("final_info", {}).get("episode", {}).pop("t", None)  # wall-clock seconds
                _equal(ia, ib)
        assert ended >= 6
        assert ours.get_attr("render_mode") == ref.get_attr("render_mode")
    finally:
        ours.close()
        ref.close()


def test_sb3_trains_through_the_adapter_on_a_sharded_env() -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.monitor import Monitor

    vec = VectorEnvAdapter(ShardedVectorEnv(env_fns("PointNav", CFG, 4, 4), workers=2), wrappers=(Monitor,))
    try:
        model = PPO(
            "MlpPolicy",
            vec,
            n_steps=32,
            batch_size=64,
            n_epochs=1,
            seed=0,
            device="cpu",
            policy_kwargs={"net_arch": [16, 16]},
        )
        model.learn(256)
        assert model.num_timesteps == 256 and len(model.ep_info_buffer) > 0  # episodes ended and were logged
        assert vec.get_attr("spec", indices=[1])[0].id == "curbside/PointNav-v0"
    finally:
        vec.close()


def _broken() -> gym.Env:
    raise RuntimeError("scene file missing (a test)")


def test_a_failing_worker_raises_its_traceback_and_bad_shapes_are_refused() -> None:
    fns = env_fns("PointNav", CFG, 2, 2)
    with pytest.raises(RuntimeError, match="scene file missing"):
        ShardedVectorEnv([fns[0], _broken], workers=2)
    with pytest.raises(ValueError, match="workers must be in"):
        ShardedVectorEnv(fns, workers=3)


def test_add_info_builds_gymnasiums_arrays() -> None:
    """ShardedVectorEnv's leaner _add_info gives Gymnasium's arrays: the same keys, dtypes, masks and values."""
    infos = [
        {
            "cost": 0.5,
            "n": 3,
            "ok": True,
            "kinds": ["object"],
            "why": None,
            "v": np.float32(2.0),
            "img": np.ones((2, 3), dtype=np.uint8),
            "final_obs": np.zeros(4),
            "final_info": {"episode": {"r": 1.5, "l": 7}, "end_reason": "goal"},
        },
        {},
        {
            "cost": 1,
            "ok": False,
            "kinds": [],
            "why": "stuck",
            "v": np.float32(-1.0),
            "img": np.zeros((2, 3), dtype=np.uint8),
            "extra": {"deep": {"x": 1.0}},
        },
    ]

    def batched(add: object, venv: object) -> dict:
        out: dict = {}
        for i, info in enumerate(infos):
            out = add(venv, out, info, i)
        return out

    class Bare(ShardedVectorEnv):
        def __init__(self) -> None:  # only num_envs: _add_info reads nothing else
            self.num_envs = len(infos)

    venv = Bare()
    ours, ref = batched(ShardedVectorEnv._add_info, venv), batched(gym.vector.VectorEnv._add_info, venv)

    def same(a: dict, b: dict) -> None:
        assert a.keys() == b.keys()
        for k, x in a.items():
            y = b[k]
            if isinstance(x, dict):
                same(x, y)
            else:
                assert x.dtype == y.dtype and x.shape == y.shape, k
                assert [repr(v) for v in x.ravel()] == [repr(v) for v in y.ravel()], k

    same(ours, ref)


@pytest.mark.parametrize(
    "infos",
    [
        [{"x": {"a": 1}}, {"x": 2}],  # a dict, then a plain value: Gymnasium keeps the dict (the value under key 1)
        [{"x": 1}, {"_x": 5}],  # a key named like an earlier key's mask
        [{"x": 1, "_x": 5}],
    ],
)
def test_add_info_matches_gymnasium_on_odd_infos(infos: list[dict]) -> None:
    """Where envs' infos disagree in kind, or a key looks like a mask, _add_info still gives Gymnasium's dict."""

    class Bare(ShardedVectorEnv):
        def __init__(self) -> None:  # only num_envs: _add_info reads nothing else
            self.num_envs = 3

    venv = Bare()
    ours: dict = {}
    ref: dict = {}
    for i, info in enumerate(infos):
        ours = ShardedVectorEnv._add_info(venv, ours, info, i)
        ref = gym.vector.VectorEnv._add_info(venv, ref, info, i)
    _equal(ours, ref)
