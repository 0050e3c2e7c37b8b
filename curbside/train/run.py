"""One entry point for every baseline: `train(algo, task, out, ...)` picks online RL, offline RL or imitation."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from curbside.train.policies import check_algo


def train(algo: str, task: str, out: Path, *, steps: int, env_config: Mapping[str, Any] | None = None,
          n_envs: int = 8, num_scenes: int = 64, seed: int = 0, demos: Path | None = None, resume: bool = False,
          eval_every: int = 0, hparams: Mapping[str, Any] | None = None, progress: bool = True,
          subprocess: bool = True, executor: str = "local", num_env_runners: int = 2,
          address: str | None = None) -> Path:
    """Train `algo` on `task`'s train split; write run.json and the policy into `out`; return the policy path.

    `executor` "ray" trains PPO (or PPO-ET) on Ray RLlib with `num_env_runners` env runners on the cluster at
    `address` (curbside.train.rllib), into the same layout; "local" is SB3 with `n_envs` envs in local processes.
    """
    from curbside.train.online import ONLINE_ALGOS, PPO_DEFAULTS, train_online

    check_algo(algo)
    out = Path(out)
    cfg = dict(env_config or {})
    h = {**PPO_DEFAULTS, **(hparams or {})}
    if executor not in ("local", "ray"):
        from curbside.config import ConfigError
        raise ConfigError(f"training runs on executor local (SB3, envs in local processes) or ray (RLlib), got "
                          f"{executor!r}")
    if executor == "ray":
        from curbside.train.rllib import train_rllib
        return train_rllib(algo, task, out, steps=steps, env_config=cfg, n_envs=n_envs, num_env_runners=num_env_runners,
                           num_scenes=num_scenes, hparams=h, seed=seed, resume=resume, eval_every=eval_every,
                           address=address, progress=progress)
    if algo in ONLINE_ALGOS:
        return train_online(algo, task, out, steps=steps, env_config=cfg, n_envs=n_envs, num_scenes=num_scenes,
                            hparams=h, seed=seed, resume=resume, eval_every=eval_every, progress=progress,
                            subprocess=subprocess)
    from curbside.train.demos import load_demos

    assert demos is not None, f"{algo} needs demonstrations"
    transitions, meta = load_demos(demos)
    out.mkdir(parents=True, exist_ok=True)
    (out / "run.json").write_text(json.dumps({"algo": algo, "task": task, "steps": steps, "seed": seed,
                                              "demos": str(demos), "demos_meta": meta, "env_config": cfg,
                                              "n_envs": n_envs, "num_scenes": num_scenes}, indent=2, default=str))
    import gymnasium as gym

    import sim  # noqa: F401
    from curbside.train.envs import env_id, make_vec_env, split_config

    probe = gym.make(env_id(task), config=split_config(cfg, "train", 1))
    obs_space, act_space = probe.observation_space, probe.action_space
    probe.close()
    if transitions.obs.shape[1:] != obs_space.shape:
        from curbside.config import ConfigError
        raise ConfigError(f"the demonstrations' observations have shape {transitions.obs.shape[1:]}, the env's "
                          f"{obs_space.shape}; collect them again with the same env config")
    if algo in ("iql", "td3bc"):
        from curbside.train.offline import train_offline
        return train_offline(algo, transitions, out, steps=steps, seed=seed, progress=progress)
    if algo == "bc":
        from curbside.train.imitate import train_bc
        return train_bc(transitions, out, steps=steps, observation_space=obs_space, action_space=act_space, seed=seed,
                        batch_size=int((hparams or {}).get("batch_size", 256)), progress=progress)
    from curbside.train.imitate import train_gail

    vec = make_vec_env(task, cfg, n_envs, num_scenes, subprocess=subprocess, seed=seed)
    try:
        return train_gail(transitions, out, steps=steps, venv=vec, hparams=h, seed=seed)
    finally:
        vec.close()
