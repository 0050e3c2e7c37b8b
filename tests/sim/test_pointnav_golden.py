"""PointNav's golden episodes: the hash of observations, rewards and infos of fixed episodes on both backends.

Speed-ups of the batched env (its footprint test, the atlas, the LiDAR march) and of the PyBullet env claim to keep
behaviour bit for bit; this test holds them to it. The episodes: the PyBullet env under the default config (the
expert, then seeded random actions) and under `paper`'s world (MetaUrban's ego, its cost and episode ends), and the
batched env of four sub-envs under both, seeded random actions with contacts, resets and a pool of routes.

GOLDEN is re-recorded only for a change that alters the episodes on purpose, after checking that the episodes keep
their lengths and outcomes; the commit that re-records it says why. numpy's float results differ between CPU kinds
(its AVX-512 build uses SVML for power, arctan2, hypot), so the hash is kept per CPU kind and the test skips on a kind
without one: `python tests/sim/test_pointnav_golden.py` prints it and the CPU kind (with
NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" an AVX-512 machine gives the AVX2 hash).
"""

from __future__ import annotations

import hashlib
import warnings
from typing import Any

import numpy as np

from tests.golden import check_golden, cpu_kind

# Recorded on the commit before the batched env's footprint kernel, in-place atlas growth and one-thread rollouts; the
# AVX-512 and AVX2 runs agree.
GOLDEN = {
    ("x86_64", "AVX2"): "e2822b84b3a0ade6db05d80a9340db43cb0d228382597c869d4ce83bb09f2703",
    ("x86_64", "AVX512_SKX"): "e2822b84b3a0ade6db05d80a9340db43cb0d228382597c869d4ce83bb09f2703",
}


def _numbers(info: dict[str, Any]) -> np.ndarray:
    """The info's numeric fields in key order (arrays flattened; metrics at episode end included)."""
    out: list[float] = []
    for _, v in sorted(info.items()):
        if isinstance(v, (int, float, bool, np.number)):
            out.append(float(v))
        elif isinstance(v, np.ndarray) and v.dtype != object:
            out.extend(np.asarray(v, dtype=np.float64).ravel().tolist())
        elif isinstance(v, dict):
            out.extend(_numbers(v).tolist())
    return np.array(out)


def golden_digest() -> tuple[str, int]:
    """(sha256 of the golden episodes, env steps taken)."""
    from curbside.train.protocols import PAPER_WORLD
    from sim.batched import BatchedPointNav
    from sim.envs.pointnav import PointNavEnv
    from sim.expert import PurePursuitExpert
    from sim.scene import generate_scene

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        spec = generate_scene({"blocks": 2, "object_density": 2.0, "terrain": {"density": 0.0}}, 3)
    default = {"scene_spec": spec, "route_length": [20.0, 40.0], "horizon": 150}
    paper = {**default, **{k: v for k, v in PAPER_WORLD.items() if k not in ("route_length", "horizon")}}
    h, steps = hashlib.sha256(), 0

    def feed(*arrays: Any) -> None:
        for a in arrays:
            h.update(np.ascontiguousarray(a).tobytes())

    for config in (default, paper):
        env = PointNavEnv(config)
        expert = PurePursuitExpert.for_machine(env.spec_machine)
        for seed in (0, 1, 2):
            obs, info = env.reset(seed=seed)
            feed(obs, _numbers(info))
            rng = np.random.default_rng(seed)
            for _ in range(150):
                action = expert.act(env) if seed == 0 else rng.uniform(-1.0, 1.0, 2)
                obs, reward, term, trunc, info = env.step(action)
                steps += 1
                feed(obs, np.float64(reward), _numbers(info))
                if term or trunc:
                    break
        env.close()
        batched = BatchedPointNav(4, {**config, "route_pool": 2})
        obs, info = batched.reset(seed=10)
        feed(obs, _numbers(info))
        rng = np.random.default_rng(10)
        for _ in range(200):
            action = np.clip(rng.normal([0.0, 0.5], 0.6, (4, 2)), -1.0, 1.0)
            obs, reward, term, trunc, info = batched.step(action)
            steps += 4
            feed(obs, reward, term, trunc, _numbers({k: v for k, v in info.items() if k != "final_obs"}))
        batched.close()
    return h.hexdigest(), steps


def test_golden_episodes() -> None:
    check_golden(GOLDEN, golden_digest, 1500, "tests/sim/test_pointnav_golden.py")


if __name__ == "__main__":
    print(*golden_digest(), cpu_kind())
