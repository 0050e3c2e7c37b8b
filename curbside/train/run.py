"""One entry point for every baseline: `train(algo, task, out, ...)` picks online RL, offline RL or imitation under a
protocol (curbside.train.protocols), on a split, from scratch or from a trained run."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from curbside.train.defaults import RUN_EVAL_EVERY, RUN_N_ENVS, RUN_NUM_SCENES, RUN_SEED
from curbside.train.policies import check_algo
from kernel.config import ConfigError

BACKENDS = ("pybullet", "batched")  # the PyBullet envs (the reference), or sim.batched (flat ground)
BATCHED_ALGOS = ("ppo", "ppo_lag", "ppo_et", "gail")  # what sim.batched can train: PPO and GAIL's PPO generator


def check_backend(backend: str, task: str, algo: str) -> str:
    """`backend` if it can train `algo` on `task`; otherwise a ConfigError that names what can."""
    if backend not in BACKENDS:
        raise ConfigError(f"unknown backend {backend!r}; valid: {', '.join(BACKENDS)}")
    if backend == "batched" and algo not in BATCHED_ALGOS:
        raise ConfigError(
            f"the batched backend trains {', '.join(BATCHED_ALGOS)} (the learners that step envs); train {algo} "
            "with --backend pybullet"
        )
    return backend


def resolve_run(
    algo: str,
    task: str,
    *,
    protocol: str = "curbside",
    env_config: Mapping[str, Any] | None = None,
    n_envs: int | None = None,
    num_scenes: int | None = None,
    split: str = "train",
    hparams: Mapping[str, Any] | None = None,
    backend: str = "pybullet",
) -> dict[str, Any]:
    """What a run trains with: the protocol's env config (the caller's merged key by key), envs (the protocol's for
    `backend`), scenes of `split` and `algo`'s hyper-parameters, each overridden by the caller's values (None keeps
    the protocol's)."""
    from curbside.train.envs import SPLITS
    from curbside.train.protocols import deep_merge, ppo_hparams
    from curbside.train.protocols import protocol as get_protocol

    check_algo(algo)
    proto = get_protocol(protocol)
    if split not in SPLITS:
        raise ConfigError(f"unknown split {split!r}; valid: {', '.join(SPLITS)}")
    cfg = deep_merge(proto.env_for(task), env_config)
    if "split" in (env_config or {}) and env_config["split"] != split:  # type: ignore[index]
        raise ConfigError(
            f"config.split {env_config['split']!r} differs from --split {split!r}; "  # type: ignore[index]
            "choose the training split with --split"
        )
    cfg.pop("split", None)
    envs = int(n_envs or (proto.n_envs if backend == "batched" else proto.pybullet_envs))
    # An experiment's scene count (ablation b) is env config; a run records it once, as its num_scenes, so the
    # recorded and the expected env configs of a run compare equal whichever way the count was given.
    configured_scenes = cfg.pop("num_scenes", None)
    num_scenes = num_scenes or configured_scenes
    h = proto.algo_hparams(algo)
    ppo_family = algo in ("ppo", "ppo_lag", "ppo_et", "gail")
    # n_steps and SB3's target_kl (stop a batch's epochs once the approximate KL passes 1.5 x target_kl) are
    # overrides only: no protocol sets them, so a protocol's recorded runs keep resuming under its values.
    valid = {*h, "net_arch", *(("n_steps", "target_kl") if ppo_family else ())}
    unknown = sorted(set(hparams or {}) - valid)
    if unknown:
        raise ConfigError(f"unknown {algo} hyper-parameter(s) {unknown}; valid: {', '.join(sorted(valid))}")
    target_kl = (hparams or {}).get("target_kl")
    if target_kl is not None and (
        isinstance(target_kl, bool) or not isinstance(target_kl, (int, float)) or target_kl <= 0
    ):
        raise ConfigError(f"hparams.target_kl must be a number > 0 (e.g. 0.01), got {json.dumps(target_kl)}")
    h = {**h, **(hparams or {})}
    if ppo_family:
        h = ppo_hparams(h, envs)
    return {
        "protocol": proto.name,
        "env_config": cfg,
        "n_envs": envs,
        "split": split,
        "hparams": h,
        "num_scenes": int(num_scenes or proto.scenes(split)),
    }


def as_recorded(value: Any) -> Any:
    """`value` as JSON reads it back (tuples as lists, mapping proxies as dicts): run.json's form."""
    return json.loads(json.dumps(value, default=lambda o: dict(o) if isinstance(o, Mapping) else list(o)))


def changed_keys(recorded: Mapping[str, Any], expected: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """The keys of each part of `expected` (env_config, hparams) whose value in a run.json's `recorded` content
    differs, as "part.key"."""
    changed = []
    for part, want_part in expected.items():
        have, want = as_recorded(recorded.get(part, {})), as_recorded(want_part)
        changed += [f"{part}.{k}" for k in sorted({*have, *want}) if have.get(k) != want.get(k)]
    return changed


def check_resume_config(out: Path, env_config: Mapping[str, Any], hparams: Mapping[str, Any]) -> None:
    """A resumed run goes on under the env config and hyper-parameters it started with: a ConfigError naming the
    values that differ (a protocol changed since, or other overrides) and how to continue."""
    recorded = json.loads((Path(out) / "run.json").read_text())
    given = {"env_config": env_config, "hparams": hparams}
    changed = changed_keys(recorded, given)
    if changed:
        part, key = changed[0].split(".", 1)
        was, now = recorded.get(part, {}).get(key), as_recorded(given[part]).get(key)
        raise ConfigError(
            f"--resume of {out}: it trained with {changed[0]} = {json.dumps(was)}, this command gives "
            f"{json.dumps(now)} ({len(changed)} value(s) differ: {', '.join(changed)}); pass the run's values with "
            "--config or --hparams to continue it, or train into another --out"
        )


def check_run_folder(out: Path, algo: str, task: str, resume: bool) -> None:
    """A new run needs a folder that holds none (a run is never overwritten); `resume` needs the folder of a run of
    the same algorithm and task. ConfigError with the fix otherwise."""
    f = Path(out) / "run.json"
    if not f.is_file():
        if resume:
            raise ConfigError(f"--resume: {out} holds no run to continue (no run.json); drop --resume to start one")
        return
    try:
        run = json.loads(f.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise ConfigError(f"{f} is not a run's JSON; move the folder away or train into another --out") from None
    held = f"a {run.get('algo', '?')} run on {run.get('task', '?')}" if isinstance(run, dict) else "a damaged run.json"
    if not resume:
        raise ConfigError(f"{out} already holds {held}; continue it with --resume or train into another --out")
    if not isinstance(run, dict) or (run.get("algo"), run.get("task")) != (algo, task):
        raise ConfigError(f"--resume of {out}: it holds {held}, not {algo} on {task}; train into another --out")


def train(
    algo: str,
    task: str,
    out: Path,
    *,
    steps: int,
    protocol: str = "curbside",
    backend: str = "pybullet",
    split: str = "train",
    env_config: Mapping[str, Any] | None = None,
    n_envs: int | None = RUN_N_ENVS,
    num_scenes: int | None = RUN_NUM_SCENES,
    seed: int = RUN_SEED,
    demos: Path | None = None,
    resume: bool = False,
    init_from: Path | None = None,
    eval_every: int = RUN_EVAL_EVERY,
    eval_episodes: int | None = None,
    hparams: Mapping[str, Any] | None = None,
    progress: bool = True,
    subprocess: bool = True,
    executor: str = "local",
    num_env_runners: int = 2,
    address: str | None = None,
) -> Path:
    """Train `algo` on `task`'s `split` under `protocol`; write run.json and the policy into `out`; return the policy
    path.

    `backend` "batched" steps the online algorithms' envs in sim.batched; evaluation always runs on the
    PyBullet env. `init_from` starts from a trained run's policy (same algorithm family, task and observations).
    `executor` "ray" trains PPO (or PPO-ET) on Ray RLlib with `num_env_runners` env runners on the cluster at
    `address` (curbside.train.rllib), into the same layout; "local" is SB3 with `n_envs` envs.
    """
    from curbside.train.online import ONLINE_ALGOS, train_online
    from curbside.train.protocols import protocol as get_protocol

    check_algo(algo)
    check_backend(backend, task, algo)
    check_run_folder(Path(out), algo, task, resume)
    r = resolve_run(
        algo,
        task,
        protocol=protocol,
        env_config=env_config,
        n_envs=n_envs,
        num_scenes=num_scenes,
        split=split,
        hparams=hparams,
        backend=backend,
    )
    cfg, h, envs, scenes = r["env_config"], r["hparams"], r["n_envs"], r["num_scenes"]
    if resume:
        check_resume_config(Path(out), cfg, h)
    proto = get_protocol(protocol)
    episodes = int(eval_episodes or proto.curve_episodes)
    out = Path(out)
    if executor not in ("local", "ray"):
        raise ConfigError(
            f"training runs on executor local (SB3, envs in local processes) or ray (RLlib), got {executor!r}"
        )
    if executor == "ray":
        if init_from is not None or split != "train" or backend != "pybullet":
            raise ConfigError(
                "--executor ray trains from scratch on the train split with the PyBullet envs; drop "
                "--init-from, --split and --backend, or use --executor local"
            )
        from curbside.train.rllib import train_rllib

        return train_rllib(
            algo,
            task,
            out,
            steps=steps,
            env_config=cfg,
            n_envs=envs,
            num_env_runners=num_env_runners,
            num_scenes=scenes,
            hparams=h,
            seed=seed,
            resume=resume,
            eval_every=eval_every,
            address=address,
            progress=progress,
            meta={"protocol": r["protocol"], "split": split, "backend": backend},
        )
    meta = {
        "protocol": r["protocol"],
        "split": split,
        "backend": backend,
        "init_from": None if init_from is None else str(init_from),
    }
    if algo in ONLINE_ALGOS:
        return train_online(
            algo,
            task,
            out,
            steps=steps,
            env_config=cfg,
            n_envs=envs,
            num_scenes=scenes,
            hparams=h,
            seed=seed,
            resume=resume,
            eval_every=eval_every,
            eval_episodes=episodes,
            eval_actions=proto.eval_actions,
            progress=progress,
            subprocess=subprocess,
            split=split,
            backend=backend,
            backend_config=proto.backend_config(backend),
            init_from=init_from,
            meta=meta,
        )
    from curbside.train.demos import load_demos

    if demos is None:
        raise ConfigError(
            f"{algo} learns from demonstrations: pass --demos DIR (collect with `curbside demos collect --task {task}`)"
        )
    transitions, demos_meta = load_demos(demos)
    if demos_meta.get("task", task) != task:
        raise ConfigError(
            f"the demonstrations at {demos} are of {demos_meta['task']}, not {task}; collect {task} "
            f"demonstrations with `curbside demos collect --task {task}`"
        )
    out.mkdir(parents=True, exist_ok=True)
    (out / "run.json").write_text(
        json.dumps(
            {
                "algo": algo,
                "task": task,
                "steps": steps,
                "seed": seed,
                "demos": str(demos),
                "demos_meta": demos_meta,
                "env_config": cfg,
                "n_envs": envs,
                "num_scenes": scenes,
                "hparams": h,
                **meta,
            },
            indent=2,
            default=str,
        )
    )
    import gymnasium as gym

    import sim  # noqa: F401
    from curbside.train.envs import env_id, split_config

    probe = gym.make(env_id(task), config=split_config(cfg, split, 1))
    obs_space, act_space = probe.observation_space, probe.action_space
    probe.close()
    if transitions.obs.shape[1:] != obs_space.shape:
        raise ConfigError(
            f"the demonstrations' observations have shape {transitions.obs.shape[1:]}, the env's "
            f"{obs_space.shape}; collect them again with the same env config"
        )
    if algo in ("iql", "td3bc"):
        from curbside.train.offline import train_offline

        return train_offline(algo, transitions, out, steps=steps, hparams=h, seed=seed, progress=progress)
    if algo == "bc":
        from curbside.train.imitate import train_bc

        return train_bc(
            transitions,
            out,
            steps=steps,
            observation_space=obs_space,
            action_space=act_space,
            seed=seed,
            hparams=h,
            progress=progress,
        )
    import torch

    from curbside.train.envs import make_training_vec
    from curbside.train.imitate import train_gail

    # GAIL's generator steps the backend's envs, with its scene reuse (run.json keeps the env_config alone); the
    # batched envs' shards rest while the discriminator and the generator update, as PPO's do.
    torch.set_num_threads(2 if backend == "batched" else 1)
    train_cfg = {**cfg, **proto.backend_config(backend)}
    vec = make_training_vec(
        task, train_cfg, envs, scenes, backend=backend, split=split, seed=seed, subprocess=subprocess
    )
    try:
        return train_gail(transitions, out, steps=steps, venv=vec, hparams=h, seed=seed, resume=resume)
    finally:
        vec.close()
