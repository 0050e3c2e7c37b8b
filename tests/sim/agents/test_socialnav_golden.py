"""SocialNav's golden episodes: the hash of observations, rewards, infos and cohabitant states of fixed episodes.

Speed-ups of the crowd, traffic, bodies and LiDAR claim to preserve behaviour bit for bit; this test
holds them to it. The episodes cover agents of six kinds spawned along the route (the ego meets them) and on the
sidewalks (the bench crowd), standing groups that disperse or walk on, road crossings, pushes, idling, running,
and dense traffic that turns at junctions, respawns and yields at crosswalks; the expert drives two episodes,
seeded random actions (collisions) the others.

GOLDEN is re-recorded only for a change that alters the episodes on purpose (the contact solver's rounding, how
routes are sampled, a key added to the per-step info), after checking that the episodes keep their lengths and
outcomes; the commit that re-records it says why. numpy's float results differ between CPU kinds
(its AVX-512 build uses SVML for power, arctan2, hypot), so the hash is kept per CPU kind and the test skips on a
kind without one: compute it there on a behaviour-preserving commit (`python tests/sim/agents/test_socialnav_golden.py`
prints it and the CPU kind) and add it.
"""

from __future__ import annotations

import hashlib
import warnings
from typing import Any

import numpy as np

from tests.golden import check_golden, cpu_kind

# Per CPU kind: numpy's transcendental kernels (SVML on AVX-512) and hence the doubles depend on it.
# The AVX-512 hash comes from a commit whose episodes give the AVX2 hash with numpy's AVX-512 kernels off
# (NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR"), so both record the same behaviour; it is the same
# with only the AVX512_ICL and AVX512_SPR kernels off (a Skylake-X-level machine).
GOLDEN = {
    ("x86_64", "AVX2"): "3514e6ed5906e1d91dba352b160cb85bd28c9c416c7cb156d5fd14ed86cc8981",
    ("x86_64", "AVX512_SKX"): "a7686d288d2159340ff1a57028bbe26ad14b64b86f06b348fa37e87fb30fa18d",
}

ROUTE_CROWD = {
    "counts": {
        "pedestrian": 16,
        "cyclist": 3,
        "wheelchair_user": 3,
        "scooter_rider": 2,
        "robot_dog": 1,
        "delivery_robot": 1,
    },
    "group_prob": 0.4,
    "cross_prob": 0.4,
    "stuck_steps": 10,
    "regoal_steps": 40,
    "idle_prob": 0.3,
    "idle_time": [0.5, 2.0],
    "group_time": [1.0, 4.0],
    "run_prob": 0.3,
    "spawn_area": "route",
}


def _numbers(info: dict[str, Any]) -> np.ndarray:
    """The info's numeric fields in key order (metrics at episode end included)."""
    return np.array([float(v) for k, v in sorted(info.items()) if isinstance(v, (int, float, bool, np.number))])


def golden_digest() -> tuple[str, int]:
    """(sha256 of the golden episodes, env steps taken)."""
    from sim.bench import SOCIALNAV_BENCH
    from sim.envs.socialnav import SocialNavEnv
    from sim.expert import PurePursuitExpert
    from sim.scene import generate_scene

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # 97 objects, 3 crosswalks, junctions. Terrain off: the hash holds the step code to the behaviour it had
        # before terrain existed (docs/terrain.md); terrain's own physics is tested in tests/sim/test_scene_terrain.py.
        spec = generate_scene({"blocks": 2, "object_density": 2.0, "terrain": {"density": 0.0}}, 1)
    base = {"scene_spec": spec, "route_length": [20.0, 40.0], "horizon": 120, "vehicles": {"traffic_density": 3.0}}
    h, steps = hashlib.sha256(), 0

    def feed(*arrays: Any) -> None:
        for a in arrays:
            h.update(np.ascontiguousarray(a).tobytes())

    expert = PurePursuitExpert()
    runs = ((ROUTE_CROWD, (0, 1, 2, 3)), (SOCIALNAV_BENCH["agents"], (5, 6)))
    for agents, seeds in runs:
        env = SocialNavEnv({**base, "agents": agents})
        for seed in seeds:
            obs, info = env.reset(seed=seed)
            feed(obs, np.array([float(info["route_length"]), float(info["horizon"])]))
            rng = np.random.default_rng(seed)
            for _ in range(120):
                action = expert.act(env) if seed % 2 == 0 else rng.uniform(-1.0, 1.0, 2)
                obs, reward, term, trunc, info = env.step(action)
                steps += 1
                feed(
                    obs,
                    np.float64(reward),
                    _numbers(info),
                    env.agent_states()[["x", "y", "vx", "vy"]],
                    env.vehicle_states()[["x", "y", "vx", "vy", "yaw"]],
                )
                if term or trunc:
                    break
            stats = {
                **env.crowd.behaviour_stats(),
                **env.crowd.goal_stats(),
                "respawns": env.traffic.respawns,
                "turns": env.traffic.turns,
                "continued": env.traffic.continued,
            }
            feed(np.array([float(stats[k]) for k in sorted(stats)]))
        env.close()
    return h.hexdigest(), steps


def test_golden_episodes() -> None:
    check_golden(GOLDEN, golden_digest, 500, "tests/sim/agents/test_socialnav_golden.py")


if __name__ == "__main__":
    print(*golden_digest(), cpu_kind())


def test_scalar_reward_matches_batch() -> None:
    """Reward.__call__ (Python floats, every env step) gives batch()'s double (numpy, the batched env) bit for bit."""
    from sim.tasks.pointnav import REWARD_PRESETS, Reward
    from sim.tasks.termination import StepContext, StepEnd

    rng = np.random.default_rng(0)
    for preset in ({}, REWARD_PRESETS["paper"], {"floor": True}):
        reward = Reward(**preset)
        for _ in range(3000):
            args = [float(v) for v in rng.normal(size=5)]
            if rng.random() < 0.1:
                args[2] = float("nan")  # a NaN offset: neither the scalar nor the batch path penalises it
            flags = [bool(v) for v in rng.random(4) < 0.2]
            progress, new_progress, lateral, d_steer, speed = args
            step = StepContext(
                steps=1,
                progress=progress,
                new_progress=new_progress,
                max_progress=0.0,
                route_length=1.0,
                lateral=lateral,
                d_steer=d_steer,
                speed=speed,
                tilt=0.0,
                collided=flags[0],
                in_contact=flags[0],
                cost_total=0.0,
                on_walkable=lambda: True,
            )
            end = StepEnd(succeeded=flags[1], out_of_route=flags[2], stuck=flags[3])
            a, b = reward(step, end), float(reward.batch(*args, *flags))
            assert np.float64(a).tobytes() == np.float64(b).tobytes(), (preset, args, flags, a, b)


def _locate_numpy(line: Any, x: float, y: float, s_hint: float | None) -> tuple[float, float]:
    """Polyline.locate as numpy computed it before its numba kernel (the reference for the kernel's doubles)."""
    import math

    if s_hint is None:
        k0, k1 = 0, len(line.seg)
    else:
        k0 = max(int(np.searchsorted(line.s, s_hint - 3.0)) - 1, 0)
        k1 = min(int(np.searchsorted(line.s, s_hint + 8.0)) + 1, len(line.seg))
    a, d = line.points[k0:k1], line.seg[k0:k1]
    qx, qy = x - a[:, 0], y - a[:, 1]
    t = np.clip((qx * d[:, 0] + qy * d[:, 1]) / (line.seg_len[k0:k1] ** 2), 0.0, 1.0)
    ex, ey = qx - t * d[:, 0], qy - t * d[:, 1]
    dist2 = ex * ex + ey * ey
    k = int(np.argmin(dist2))
    cross = d[k, 0] * qy[k] - d[k, 1] * qx[k]
    return float(line.s[k0 + k] + t[k] * line.seg_len[k0 + k]), math.sqrt(float(dist2[k])) * (
        1.0 if cross >= 0 else -1.0
    )


def test_locate_kernel_matches_numpy() -> None:
    """Polyline.locate (numba; the route tracker, every env step) gives the numpy formula's doubles."""
    from sim.scene.polyline import Polyline

    rng = np.random.default_rng(0)
    for _ in range(40):
        pts = np.cumsum(rng.normal(size=(int(rng.integers(2, 40)), 2)) * rng.uniform(0.1, 3.0), axis=0)
        line = Polyline(pts)
        for _ in range(50):
            x, y = (pts[rng.integers(len(pts))] + rng.normal(size=2) * 2.0).tolist()
            hint = None if rng.random() < 0.3 else float(rng.uniform(0.0, line.length))
            assert np.array(line.locate(x, y, hint)).tobytes() == np.array(_locate_numpy(line, x, y, hint)).tobytes()
