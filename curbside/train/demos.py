"""Expert demonstrations as Minari datasets (the Farama standard for offline RL), and reading them back as
arrays for the offline and imitation learners.

The demonstrator is the pure-pursuit expert (sim.expert) with Gaussian action noise of std `noise`, plus,
with probability `random_prob` per episode, a fully random episode: noise brings the success rate near the
paper's ~60 % mix of good and failed driving (noise 0.7 gives 0.6-0.7 on both tasks), which offline RL needs to learn what not to do.
With `policy` (a trained PPO-family run) a fraction `policy_fraction` of the episodes is driven by that policy (its
stochastic actions), as the paper's 80 % of demonstrations come from a trained PPO policy.
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Generator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, SupportsFloat, cast

import numpy as np

from curbside.train.defaults import DEMOS_NOISE, DEMOS_NUM_SCENES, DEMOS_RANDOM_PROB, DEMOS_SEED, DEMOS_STEPS
from curbside.train.envs import env_id, split_config
from curbside.train.progress import progress_bar
from kernel.config import ConfigError


@dataclass(frozen=True)
class Transitions:
    """Flat arrays of a demonstration set: obs, actions, rewards, next_obs, terminals, timeouts (per step)."""

    obs: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    next_obs: np.ndarray
    terminals: np.ndarray
    timeouts: np.ndarray

    def __len__(self) -> int:
        return len(self.actions)


def minari_root() -> Path:
    """Where `minari.load_dataset` looks: MINARI_DATASETS_PATH, else ~/.minari/datasets (Minari's own rule)."""
    env = os.environ.get("MINARI_DATASETS_PATH")
    return Path(env) if env is not None else Path.home() / ".minari" / "datasets"


def dataset_id(task: str) -> str:
    """The Minari id of a task's demonstrations, e.g. curbside/pointnav-expert-v0."""
    return f"curbside/{task.lower()}-expert-v0"


def collect_demos(
    task: str,
    out: Path,
    *,
    steps: int = DEMOS_STEPS,
    noise: float = DEMOS_NOISE,
    random_prob: float = DEMOS_RANDOM_PROB,
    env_config: Mapping[str, Any] | None = None,
    num_scenes: int = DEMOS_NUM_SCENES,
    seed: int = DEMOS_SEED,
    progress: bool = True,
    executor: str = "local",
    workers: int | None = None,
    address: str | None = None,
    policy: Path | None = None,
    policy_fraction: float = 0.0,
) -> dict[str, Any]:
    """Drive the noisy expert on the train split until `steps` steps (whole episodes); write a Minari dataset
    under `out` (its datasets root) and return a summary: path, episodes, steps, success rate.

    Episode k uses seed + k for the env and its own noise stream (seeded by (seed, k)), so `executor`
    (kernel.executors: local, process, or ray at `address`) may run episodes anywhere: they are kept in index
    order up to the first that reaches `steps`, and the dataset is the same whichever executor ran them.
    """
    import itertools

    import gymnasium as gym

    import sim  # noqa: F401
    from kernel.executors import run_map

    if steps < 1 or not 0.0 <= noise < 10 or not 0.0 <= random_prob <= 1.0 or not 0.0 <= policy_fraction <= 1.0:
        raise ConfigError("demos need steps >= 1, 0 <= noise < 10, 0 <= random_prob <= 1 and 0 <= policy_fraction <= 1")
    policy_file = None
    if policy is not None and policy_fraction > 0:
        from curbside.train.online import check_init_from

        policy_file = str(check_init_from(Path(policy), "ppo", task, dict(env_config or {})).resolve())
    elif policy_fraction > 0:
        raise ConfigError("a policy fraction needs --policy RUN (a trained PPO run of the task)")
    did = dataset_id(task)
    cfg = split_config(env_config, "train", num_scenes)
    env = gym.make(env_id(task), config=cfg)
    job = (env_id(task), cfg, float(noise), float(random_prob), int(seed), policy_file, float(policy_fraction))
    total, successes, by_policy = 0, 0, 0
    buffers: list[Any] = []
    try:
        with progress_bar(f"demos {task}", steps, progress) as update:
            # Endless episode indices: run_map keeps a window of episodes in flight and cancels the rest once the
            # steps are reached (those extra episodes are dropped, as a local run never starts them).
            # run_map is a generator function (annotated as returning an Iterator): close() is what cancels.
            episodes = cast(
                Generator[Any, None, None],
                run_map(
                    demo_episode, itertools.count(), executor=executor, workers=workers, address=address, args=(job,)
                ),
            )
            try:
                for episode, success in episodes:
                    successes += int(success)
                    by_policy += int(episode.source == "policy")
                    total += len(episode)
                    buffers.append(episode.buffer(len(buffers)))
                    update(total)
                    if total >= steps:
                        break
            finally:
                episodes.close()
        algorithm = f"PurePursuitExpert(noise={noise}, random_prob={random_prob})"
        if policy_file is not None:
            algorithm = f"{policy_fraction:.0%} PPO policy {policy}, the rest {algorithm}"
        meta = {
            "steps": total,
            "success_rate": successes / max(len(buffers), 1),
            "noise": noise,
            "random_prob": random_prob,
            "task": task,
            "policy": None if policy is None else str(policy),
            "policy_fraction": policy_fraction,
            "policy_episodes": by_policy,
            "catalog": cfg.get("catalog"),  # the scenes' assets (a protocol's catalog, or None: fallback boxes)
        }
        return write_dataset(
            buffers,
            env,
            out,
            did,
            algorithm=algorithm,
            meta=meta,
            description=f"{task} demonstrations on the train split: the pure-pursuit expert with "
            "Gaussian action noise (curbside demos collect).",
        )
    finally:
        env.close()


def demo_episode(k: int, job: tuple[Any, ...]) -> tuple[EpisodeRecorder, bool]:
    """Episode `k` of a collection (`job`: env id, env config, noise, random_prob, seed, policy file, policy fraction)
    and whether it succeeded; it depends on (seed, k) alone, so any worker, or a retry, records the same steps."""
    import gymnasium as gym

    import sim  # noqa: F401
    from kernel.executors import worker_state
    from sim.expert import PurePursuitExpert

    eid, cfg, noise, random_prob, seed, policy_file, policy_fraction = job
    env = worker_state(
        "demo_env", json.dumps([eid, cfg], sort_keys=True, default=str), lambda: gym.make(eid, config=dict(cfg))
    )
    expert = PurePursuitExpert.for_machine(env.unwrapped.spec_machine)
    rng = np.random.default_rng([seed, k])
    ep_seed = seed + k
    obs, _ = env.reset(seed=ep_seed)
    env.action_space.seed(ep_seed)
    random_episode = rng.random() < random_prob
    model = None
    if policy_file is not None and rng.random() < policy_fraction:
        import torch
        from stable_baselines3 import PPO

        model = worker_state("demo_policy", policy_file, lambda: PPO.load(policy_file, device="cpu"))
        torch.manual_seed(int(rng.integers(2**31)))  # the policy's own action noise, per episode
    episode = EpisodeRecorder(obs, ep_seed, "policy" if model is not None else "random" if random_episode else "expert")
    done, info = False, {}
    while not done:
        if model is not None:
            a = model.predict(obs, deterministic=False)[0]
        elif random_episode:
            a = env.action_space.sample()
        else:
            a = expert.act(env) + rng.normal(0.0, noise, 2)
        a = np.clip(a, -1, 1).astype(np.float32)
        obs, r, term, trunc, info = env.step(a)
        episode.add(a, obs, r, term, trunc)
        done = term or trunc
    return episode, bool(info["is_success"])


class EpisodeRecorder:
    """One episode's observations, actions, rewards and end flags, as Minari's EpisodeBuffer wants them."""

    def __init__(self, first_obs: Any, seed: int | None, source: str = "expert") -> None:
        self.seed = seed
        self.source = source  # who drove: expert, random or policy
        self.cols: dict[str, list] = {
            "observations": [first_obs],
            "actions": [],
            "rewards": [],
            "terminations": [],
            "truncations": [],
        }

    def add(self, action: np.ndarray, obs: Any, reward: SupportsFloat, terminated: bool, truncated: bool) -> None:
        """Record one step: the action taken and what followed."""
        for k, v in zip(
            ("actions", "observations", "rewards", "terminations", "truncations"),
            (action, obs, reward, terminated, truncated),
        ):
            self.cols[k].append(v)

    def __len__(self) -> int:
        return len(self.cols["actions"])

    def buffer(self, episode_id: int) -> Any:
        """The minari EpisodeBuffer (Dict observations are stacked per key)."""
        from minari.data_collector import EpisodeBuffer

        o = self.cols["observations"]
        obs = {k: np.asarray([x[k] for x in o]) for k in o[0]} if isinstance(o[0], dict) else np.asarray(o)
        return EpisodeBuffer(
            id=episode_id,
            seed=self.seed,
            observations=obs,
            actions=np.asarray(self.cols["actions"]),
            rewards=self.cols["rewards"],
            terminations=self.cols["terminations"],
            truncations=self.cols["truncations"],
        )


def write_dataset(
    buffers: list[Any],
    env: Any,
    out: Path,
    did: str,
    *,
    algorithm: str,
    description: str,
    meta: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Write episode buffers as the Minari dataset `did` under the datasets root `out` (replacing one of the same
    id once the new one is complete); returns its summary (id, path, episode count, Minari's step count and `meta`),
    also written to the dataset's curbside.json."""
    import shutil

    import minari

    out = Path(out).resolve()
    target = out / did
    # Written beside the previous dataset and swapped in: a killed collection leaves the old one whole.
    staging = out / f".staging-{os.getpid()}"
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    previous = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(staging)
    try:
        # Built from buffers, not minari.DataCollector: the collector needs jax for nothing more than list appends.
        with warnings.catch_warnings():
            # Minari asks for a code permalink, an e-mail and an eval env; the env spec it records is the eval env.
            warnings.filterwarnings("ignore", category=UserWarning, module="minari")
            ds = minari.create_dataset_from_buffers(
                dataset_id=did,
                buffer=buffers,
                env=env,
                algorithm_name=algorithm,
                author="curbside",
                description=description,
                data_format="arrow",
            )
            summary = {
                "dataset_id": did,
                "path": str(target),
                "episodes": len(buffers),
                "total_steps_minari": int(ds.total_steps),
                **(meta or {}),
            }
        (staging / did / "curbside.json").write_text(json.dumps(summary, indent=2))
    finally:
        if previous is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = previous
    target.parent.mkdir(parents=True, exist_ok=True)
    old = target.with_name(target.name + ".old")
    if target.exists():
        shutil.rmtree(old, ignore_errors=True)
        target.rename(old)
    (staging / did).rename(target)
    shutil.rmtree(old, ignore_errors=True)
    shutil.rmtree(staging, ignore_errors=True)
    return summary


def load_demos(path: Path) -> tuple[Transitions, dict[str, Any]]:
    """Read a dataset written by collect_demos (its folder) as flat transitions plus its summary."""
    import gymnasium as gym
    from minari import MinariDataset

    path = Path(path)
    if not (path / "data").is_dir():
        raise ConfigError(
            f"no demonstration dataset at {path}; collect one with "
            f"`curbside demos collect --task PointNav --out {path.parent.parent if path.parent != path else path}`"
        )
    ds = MinariDataset(path / "data")
    if isinstance(ds.observation_space, gym.spaces.Dict):
        raise ConfigError(
            f"the dataset at {path} holds camera (Dict) observations; the offline and imitation "
            "baselines learn from the flat vector: record it again with camera.modalities []"
        )
    cols: dict[str, list[np.ndarray]] = {
        k: [] for k in ("obs", "actions", "rewards", "next_obs", "terminals", "timeouts")
    }
    for ep in ds.iterate_episodes():
        o = np.asarray(ep.observations, dtype=np.float32)
        cols["obs"].append(o[:-1])
        cols["next_obs"].append(o[1:])
        cols["actions"].append(np.asarray(ep.actions, dtype=np.float32))
        cols["rewards"].append(np.asarray(ep.rewards, dtype=np.float32))
        cols["terminals"].append(np.asarray(ep.terminations, dtype=bool))
        cols["timeouts"].append(np.asarray(ep.truncations, dtype=bool))
    if not cols["actions"]:
        raise ConfigError(f"the dataset at {path} holds no episodes; collect it again with `curbside demos collect`")
    meta_file = path / "curbside.json"
    meta = json.loads(meta_file.read_text()) if meta_file.is_file() else {}
    return Transitions(**{k: np.concatenate(v) for k, v in cols.items()}), meta
