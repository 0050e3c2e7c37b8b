"""`curbside train` and `curbside demos`: train baselines on a split, evaluate them, collect demonstrations."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console

from curbside.cli.errors import fail, parse_config_json
from curbside.cli.executor_options import (
    Executor,
    address_option,
    check_executor_args,
    executor_option,
    workers_option,
)
from curbside.config import ConfigError

app = typer.Typer(help="Train PPO, PPO-Lag, PPO-ET, IQL, TD3+BC, BC or GAIL and evaluate them on a split.",
                  no_args_is_help=True)
demos_app = typer.Typer(help="Expert demonstrations as Minari datasets for offline RL and imitation.", no_args_is_help=True)
# run/collect defaults (--envs, --scenes, --seed, --eval-every, --steps, --noise, --random-prob) equal those of
# curbside.train.run.train and curbside.train.demos.collect_demos (literals: they import numpy);
# tests/cli/test_cli_defaults.py keeps them equal.


def _check_env_config(task: str, cfg: dict, split: str) -> None:
    """Build the env once in this process so a bad config or an empty split fails before any worker starts."""
    import gymnasium as gym

    import sim  # noqa: F401
    from curbside.train.envs import env_id, split_config

    env = gym.make(env_id(task), config=split_config(cfg, split, 1))
    env.close()


@app.command("run")
def run_cmd(
    algo: str = typer.Option("ppo", help="ppo, ppo_lag, ppo_et (online); iql, td3bc (offline, need --demos); bc, gail (imitation, need --demos)."),
    task: str = typer.Option("PointNav", help="PointNav or SocialNav."),
    out: Path = typer.Option(Path("outputs/train/run"), help="Output folder: run.json, policy, checkpoints, logs."),
    steps: int = typer.Option(200_000, min=1, help="Env steps (online, GAIL) or gradient steps (IQL, TD3+BC, BC)."),
    demos: Optional[Path] = typer.Option(None, help="Demonstration dataset folder from `curbside demos collect`."),
    envs: int = typer.Option(8, min=1, max=256, help="Parallel env workers (online algorithms and GAIL)."),
    scenes: int = typer.Option(64, min=1, help="Train-split scenes, sharded across the workers."),
    seed: int = typer.Option(0, min=0, help="Seed of the run."),
    resume: bool = typer.Option(False, help="Continue from the latest checkpoint in --out."),
    eval_every: int = typer.Option(0, min=0, help="Evaluate on the test split every N env steps (0: never)."),
    config: Optional[str] = typer.Option(None, help="Env config overrides as a JSON object."),
    executor: Executor = typer.Option("local", help="local: SB3 with --envs envs in local processes; ray: RLlib PPO "
                                      "(ppo, ppo_et) with --num-env-runners env runners on a Ray cluster (--address)."),
    num_env_runners: int = typer.Option(2, "--num-env-runners", min=1, max=1024, help="RLlib env runners "
                                        "(--executor ray), each stepping --envs / runners envs."),
    address: Optional[str] = address_option(),
) -> None:
    """Train one algorithm on the train split; the policy, logs (CSV + TensorBoard) and checkpoints go to --out."""
    from curbside.train.policies import check_algo
    from curbside.train.run import train

    cfg = parse_config_json(config)
    ex = check_executor_args(executor, address)
    try:
        check_algo(algo)
        if ex == "process":
            raise ConfigError("training runs on --executor local (SB3; --envs already steps envs in local processes) "
                              "or ray (RLlib)")
        if ex == "ray" and algo not in ("ppo", "ppo_et"):
            raise ConfigError(f"--executor ray trains ppo and ppo_et on RLlib; train {algo} with --executor local")
        if demos is not None and not (demos / "data").is_dir():
            raise ConfigError(f"no demonstration dataset at {demos}; collect one with `curbside demos collect --task {task} --out DIR` "
                              "and pass the folder it prints")
        if algo in ("iql", "td3bc", "bc", "gail") and demos is None:
            raise ConfigError(f"{algo} learns from demonstrations: pass --demos DIR (collect with `curbside demos collect --task {task}`)")
        _check_env_config(task, cfg, "train")
    except (ConfigError, ValueError, FileNotFoundError) as e:
        raise fail(str(e)) from None
    path = train(algo, task, out, steps=steps, env_config=cfg, n_envs=envs, num_scenes=scenes, seed=seed,
                 demos=demos, resume=resume, eval_every=eval_every, executor=ex, num_env_runners=num_env_runners,
                 address=address)
    Console(stderr=True).print(f"[green]trained[/] {algo} on {task}: {path}", highlight=False)


@app.command("ppo")
def ppo_cmd(
    task: str = typer.Option("PointNav", help="PointNav or SocialNav."),
    out: Path = typer.Option(Path("outputs/train/ppo"), help="Output folder: run.json, policy, checkpoints, logs."),
    steps: int = typer.Option(200_000, min=1, help="Env steps."),
    envs: int = typer.Option(8, min=1, max=256, help="Parallel envs (in all)."),
    scenes: int = typer.Option(64, min=1, help="Train-split scenes, sharded across the workers or env runners."),
    seed: int = typer.Option(0, min=0, help="Seed of the run."),
    resume: bool = typer.Option(False, help="Continue from the latest checkpoint in --out."),
    eval_every: int = typer.Option(0, min=0, help="Evaluate on the test split every N env steps (0: never)."),
    config: Optional[str] = typer.Option(None, help="Env config overrides as a JSON object."),
    executor: Executor = typer.Option("local", help="local (SB3) or ray (RLlib PPO on a Ray cluster)."),
    num_env_runners: int = typer.Option(2, "--num-env-runners", min=1, max=1024, help="RLlib env runners (ray)."),
    address: Optional[str] = address_option(),
) -> None:
    """Train PPO (`train run --algo ppo`); with --executor ray on RLlib, env runners spread over the cluster."""
    run_cmd(algo="ppo", task=task, out=out, steps=steps, demos=None, envs=envs, scenes=scenes, seed=seed,
            resume=resume, eval_every=eval_every, config=config, executor=executor, num_env_runners=num_env_runners,
            address=address)


@app.command("eval")
def eval_cmd(
    run_dir: Path = typer.Argument(..., help="A folder written by `curbside train run`."),
    split: str = typer.Option("test", help="train, test, unseen or finetune."),
    episodes: int = typer.Option(50, min=1, help="Episodes (seeds seed..seed+N-1)."),
    seed: int = typer.Option(0, min=0, help="Seed of the first episode."),
    config: Optional[str] = typer.Option(None, help="Env config overrides as a JSON object (default: the run's)."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Evaluate a trained policy on a split: SR, SPL, SNS (SocialNav), Cost."""
    from curbside.train.evaluate import evaluate_policy
    from curbside.train.policies import load_policy

    try:
        act, run = load_policy(run_dir)
        cfg = {**run.get("env_config", {}), **parse_config_json(config)}
        _check_env_config(run["task"], cfg, split)
    except (ConfigError, ValueError, FileNotFoundError) as e:
        raise fail(str(e)) from None
    summary = evaluate_policy(act, run["task"], cfg, split=split, episodes=episodes, seed=seed, progress=not as_json)
    summary["algo"] = run["algo"]
    if as_json:
        typer.echo(json.dumps(summary, sort_keys=True))
        return
    sns = f"  SNS {summary['sns']:.3f}" if "sns" in summary else ""
    typer.echo(f"{run['algo']} on {run['task']} {split}, {episodes} episodes: SR {summary['sr']:.3f}  "
               f"SPL {summary['spl']:.3f}{sns}  Cost {summary['cost']:.2f}")


@demos_app.command("collect")
def collect_cmd(
    task: str = typer.Option("PointNav", help="PointNav or SocialNav."),
    out: Path = typer.Option(Path("outputs/demos"), help="Minari datasets root; the dataset goes to OUT/curbside/<task>-expert-v0."),
    steps: int = typer.Option(30_000, min=1, max=10_000_000, help="Steps to record (whole episodes)."),
    noise: float = typer.Option(0.7, min=0.0, max=5.0, help="Std of the Gaussian noise added to the expert's actions."),
    random_prob: float = typer.Option(0.0, min=0.0, max=1.0, help="Fraction of fully random episodes."),
    scenes: int = typer.Option(64, min=1, help="Train-split scenes to draw episodes from."),
    seed: int = typer.Option(0, min=0, help="Seed of the first episode."),
    config: Optional[str] = typer.Option(None, help="Env config overrides as a JSON object."),
    executor: Executor = executor_option(),
    workers: Optional[int] = workers_option(),
    address: Optional[str] = address_option(),
) -> None:
    """Record the noisy expert on the train split as a Minari dataset; print its path and success rate.

    Episodes can run on a process pool or a Ray cluster (--executor): episode k depends on (seed, k) alone and
    the dataset keeps episodes in index order, so every executor writes the same dataset."""
    from curbside.train.demos import collect_demos

    cfg = parse_config_json(config)
    ex = check_executor_args(executor, address)
    try:
        _check_env_config(task, cfg, "train")
    except (ConfigError, ValueError, FileNotFoundError) as e:
        raise fail(str(e)) from None
    os.environ.setdefault("MINARI_DATASETS_PATH", str(out))
    summary = collect_demos(task, out, steps=steps, noise=noise, random_prob=random_prob, env_config=cfg,
                            num_scenes=scenes, seed=seed, executor=ex, workers=workers, address=address)
    typer.echo(f"{summary['path']}: {summary['episodes']} episodes, {summary['steps']} steps, "
               f"success rate {summary['success_rate']:.2f}")
