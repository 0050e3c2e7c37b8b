"""The SB3 adapter over Gymnasium's async vector env gives SB3 exactly what SB3's own SubprocVecEnv gives."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.vector import AsyncVectorEnv, AutoresetMode, SyncVectorEnv
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import SubprocVecEnv

from curbside.train.envs import env_fns, make_vec_env
from curbside.train.vec import VectorEnvAdapter, unbatch

# Short routes and a short horizon: episodes end (success, collision or truncation) within the test.
CFG = {"lidar": {"beams": 24, "low_beams": 8}, "route_length": [5.0, 12.0], "scene": {"blocks": 1}, "horizon": 40}


def test_unbatch_keeps_each_envs_values_where_its_mask_holds() -> None:
    info = {
        "a": np.array([1, 2, 3]),
        "_a": np.array([True, False, True]),
        "final_info": {"r": np.array([0.0, 5.0, 0.0]), "_r": np.array([False, True, False])},
        "_final_info": np.array([False, True, False]),
    }
    assert unbatch(info, 3) == [{"a": 1}, {"final_info": {"r": 5.0}}, {"a": 3}]


def test_the_adapter_steps_like_sb3s_subprocvecenv() -> None:
    fns = env_fns("PointNav", CFG, 2, 2)
    ours = make_vec_env("PointNav", CFG, 2, 2, seed=7)
    theirs = SubprocVecEnv(fns, start_method="forkserver")
    theirs.seed(7)
    try:
        assert isinstance(ours, VectorEnvAdapter)
        np.testing.assert_array_equal(ours.reset(), theirs.reset())
        rng = np.random.default_rng(0)
        ended = 0
        for _ in range(120):
            action = rng.uniform(-1, 1, size=(2, 2)).astype(np.float32)
            o1, r1, d1, i1 = ours.step(action)
            o2, r2, d2, i2 = theirs.step(action)
            np.testing.assert_array_equal(o1, o2)
            np.testing.assert_array_equal(r1, r2)
            np.testing.assert_array_equal(d1, d2)
            for a, b, done in zip(i1, i2, d1):
                if done:
                    ended += 1
                    np.testing.assert_array_equal(a.pop("terminal_observation"), b.pop("terminal_observation"))
                    a["episode"].pop("t"), b["episode"].pop("t")  # wall-clock seconds since the start
                    assert a["episode"] == b["episode"] and a["TimeLimit.truncated"] == b["TimeLimit.truncated"]
                assert a == b
        assert ended >= 4  # episodes ended and were reset in the same step
        assert ours.reset_infos[0].keys() == theirs.reset_infos[0].keys()
        assert ours.get_attr("render_mode") == theirs.get_attr("render_mode")
        assert ours.env_is_wrapped(Monitor) == [True, True]
    finally:
        ours.close()
        theirs.close()


def test_the_adapter_refuses_what_it_cannot_translate() -> None:
    fns = env_fns("PointNav", CFG, 2, 2)
    with pytest.raises(ValueError, match="SAME_STEP"):
        VectorEnvAdapter(AsyncVectorEnv(fns[:1], context="forkserver"))
    vec = VectorEnvAdapter(SyncVectorEnv(fns, autoreset_mode=AutoresetMode.SAME_STEP), wrappers=(Monitor,))
    try:
        vec.set_options([{"a": 1}, {"a": 2}])
        with pytest.raises(ValueError, match="one options dict"):
            vec.reset()
        vec.set_options(None)
        vec.seed(3)
        first = vec.reset()
        vec.seed(3)
        np.testing.assert_array_equal(vec.reset(), first)  # seeds reach the sub-envs
    finally:
        vec.close()
