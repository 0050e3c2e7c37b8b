"""Load a trained run folder (`run.json` + its policy file) as a callable obs -> action, whatever the algorithm."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from kernel.config import ConfigError

ALGOS = ("ppo", "ppo_lag", "ppo_et", "iql", "td3bc", "bc", "gail")
POLICY_FILES = {
    "ppo": "policy.zip",
    "ppo_lag": "policy.zip",
    "ppo_et": "policy.zip",
    "gail": "policy.zip",
    "bc": "policy.zip",
    "iql": "policy.pt",
    "td3bc": "policy.pt",
}
# Learners whose saved policy is one action per observation (d3rlpy-style actors; RLlib checkpoints load the same way).
DETERMINISTIC_ALGOS = ("iql", "td3bc")


def save_policy(model: Any, path: Path) -> Path:
    """`model.save` (an SB3 algorithm or policy) to `path` through a file beside it, swapped in whole: a kill while
    saving leaves the previous policy, never half a zip."""
    path = Path(path)
    tmp = path.with_name(f"{path.stem}.tmp{path.suffix}")
    model.save(str(tmp))
    tmp.replace(path)
    return path


def check_algo(algo: str) -> str:
    """`algo` if it is a known algorithm; otherwise a ConfigError naming the valid ones."""
    if algo not in ALGOS:
        raise ConfigError(f"unknown algorithm {algo!r}; valid: {', '.join(ALGOS)}")
    return algo


def read_run(run_dir: str | Path) -> dict[str, Any]:
    """The run.json of a training output folder (clear errors when it is not one)."""
    f = Path(run_dir) / "run.json"
    if not f.is_file():
        raise ConfigError(
            f"{run_dir} is not a training run (no run.json); train one with `curbside train run --out {run_dir}`"
        )
    run = json.loads(f.read_text())
    check_algo(run.get("algo", "?"))
    return run


def can_sample(run: dict[str, Any]) -> bool:
    """Whether the run's saved policy is a distribution that `load_policy(deterministic=False)` can draw from."""
    return run["algo"] not in DETERMINISTIC_ALGOS and run.get("engine") != "rllib"


def eval_actions_of(run: dict[str, Any], actions: str) -> str:
    """How the run's policy acts under a protocol whose rule is `actions`: "mean" for a policy that cannot sample."""
    return actions if can_sample(run) else "mean"


def load_policy(
    run_dir: str | Path, *, deterministic: bool = True
) -> tuple[Callable[[np.ndarray], np.ndarray], dict[str, Any]]:
    """(act, run) for a run folder: act(obs) returns the saved policy's action, its mean (`deterministic`) or a draw
    from its distribution (PPO family, BC and GAIL; draws follow torch's global seed)."""
    run = read_run(run_dir)
    algo = run["algo"]
    if not deterministic and not can_sample(run):
        raise ConfigError(f"a {algo} policy from {run_dir} acts deterministically only; drop the stochastic option")
    if run.get("engine") == "rllib":  # `curbside train run --executor ray`: an RLlib checkpoint folder
        from curbside.train.rllib import load_rllib_policy

        policy_dir = Path(run_dir) / "policy"
        if not policy_dir.is_dir():
            raise ConfigError(
                f"{policy_dir} is missing; the run did not finish: resume it with `curbside train run "
                f"--executor ray --resume --out {run_dir}`"
            )
        return load_rllib_policy(policy_dir), run
    path = Path(run_dir) / POLICY_FILES[algo]
    if not path.is_file():
        raise ConfigError(
            f"{path} is missing; the run did not finish: resume it with `curbside train run --resume --out {run_dir}`"
        )
    if algo in ("iql", "td3bc"):
        import torch

        from curbside.train.offline import load_actor

        actor = load_actor(path)

        def act(obs: np.ndarray) -> np.ndarray:
            with torch.no_grad():
                return actor(torch.as_tensor(np.asarray(obs, dtype=np.float32)[None])).numpy()[0]

        return act, run
    if algo == "bc":
        from stable_baselines3.common.policies import ActorCriticPolicy

        policy = ActorCriticPolicy.load(str(path), device="cpu")
        return (lambda obs: policy.predict(obs, deterministic=deterministic)[0]), run
    from stable_baselines3 import PPO

    model = PPO.load(str(path), device="cpu")
    return (lambda obs: model.predict(obs, deterministic=deterministic)[0]), run
