"""`curbside train` and `curbside demos`: train baselines on a split, evaluate them, collect demonstrations."""

from __future__ import annotations

import json
from pathlib import Path

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
from curbside.cli.extras import require
from curbside.train import defaults  # the run and collect defaults (no imports)
from kernel.config import ConfigError

app = typer.Typer(
    rich_markup_mode=None,
    help="Train PPO, PPO-Lag, PPO-ET, IQL, TD3+BC, BC or GAIL and evaluate them on a split.",
    no_args_is_help=True,
)
demos_app = typer.Typer(
    rich_markup_mode=None,
    help="Expert demonstrations as Minari datasets for offline RL and imitation.",
    no_args_is_help=True,
)


def _check_env_config(task: str, cfg: dict, split: str) -> None:
    """Build the env once in this process so a bad config or an empty split fails before any worker starts."""
    import gymnasium as gym

    import sim  # noqa: F401
    from curbside.train.envs import env_id, split_config

    env = gym.make(env_id(task), config=split_config(cfg, split, 1))
    env.close()


@app.command("run")
def run_cmd(
    algo: str = typer.Option(
        "ppo",
        help="ppo, ppo_lag, ppo_et (online); iql, td3bc (offline, need --demos); bc, gail (imitation, need --demos).",
    ),
    task: str = typer.Option("PointNav", help="PointNav or SocialNav."),
    out: Path = typer.Option(Path("outputs/train/run"), help="Output folder: run.json, policy, checkpoints, logs."),
    steps: int = typer.Option(200_000, min=1, help="Env steps (online, GAIL) or gradient steps (IQL, TD3+BC, BC)."),
    protocol: str = typer.Option(
        "curbside",
        help="Experimental protocol: curbside (learnable defaults), paper (MetaUrban's scenes, splits and "
        "hyper-parameters) or paper_realistic (paper's, driven by the realistic delivery robot); docs/protocols.md.",
    ),
    backend: str = typer.Option(
        "pybullet",
        help="Envs of online training: pybullet (the reference) or batched "
        "(sim.batched, PointNav on flat ground, many envs in one numpy pass).",
    ),
    split: str = typer.Option(
        "train", help="Split to train on: train or finetune (test and unseen are for evaluation)."
    ),
    init_from: Path | None = typer.Option(
        None,
        "--init-from",
        help="Start from this run's policy (a PPO-family run of the same task and observations): fine-tuning.",
    ),
    demos: Path | None = typer.Option(None, help="Demonstration dataset folder from `curbside demos collect`."),
    envs: int | None = typer.Option(
        defaults.RUN_N_ENVS, min=1, max=256, help="Parallel envs (online algorithms and GAIL); default: the protocol's."
    ),
    scenes: int | None = typer.Option(
        defaults.RUN_NUM_SCENES, min=1, help="Scenes of the split episodes draw from; default: the protocol's."
    ),
    seed: int = typer.Option(defaults.RUN_SEED, min=0, help="Seed of the run."),
    seeds: str | None = typer.Option(
        None,
        help="Comma-separated seeds (e.g. 0,1,2): one run each in OUT/seed_<s>, "
        "their final evaluations aggregated as mean +/- std in OUT/seeds.json.",
    ),
    resume: bool = typer.Option(False, help="Continue from the latest checkpoint in --out."),
    eval_every: int = typer.Option(
        defaults.RUN_EVAL_EVERY, min=0, help="Evaluate on the test split every N env steps (0: never)."
    ),
    eval_episodes: int | None = typer.Option(
        None, min=1, help="Episodes per learning-curve evaluation; default: the protocol's."
    ),
    config: str | None = typer.Option(None, help="Env config overrides as a JSON object."),
    hparams: str | None = typer.Option(
        None,
        help="Hyper-parameter overrides of the protocol's as a JSON object, e.g. '{\"n_epochs\": 30}' "
        "(docs/protocols.md lists each algorithm's).",
    ),
    executor: Executor = typer.Option(
        "local",
        help="local: SB3 with --envs envs in local processes; ray: RLlib PPO "
        "(ppo, ppo_et) with --num-env-runners env runners on a Ray cluster (--address).",
    ),
    num_env_runners: int = typer.Option(
        2,
        "--num-env-runners",
        min=1,
        max=1024,
        help="RLlib env runners (--executor ray), each stepping --envs / runners envs.",
    ),
    address: str | None = address_option(),
) -> None:
    """Train one algorithm on a split under a protocol; the policy, logs (CSV + TensorBoard) and checkpoints go to --out."""
    require("train", "train run")
    from curbside.train.online import check_init_from
    from curbside.train.policies import check_algo
    from curbside.train.run import check_backend, resolve_run, train

    cfg = parse_config_json(config)
    overrides = parse_config_json(hparams, "--hparams")
    ex = check_executor_args(executor, address)
    try:
        check_algo(algo)
        check_backend(backend, task, algo)
        seed_list = _parse_seeds(seeds) if seeds is not None else [seed]
        if split in ("test", "unseen"):
            raise ConfigError(f"--split {split} is held out for evaluation; train on train or finetune")
        r = resolve_run(
            algo,
            task,
            protocol=protocol,
            env_config=cfg,
            n_envs=envs,
            num_scenes=scenes,
            split=split,
            backend=backend,
            hparams=overrides,
        )
        if ex == "process":
            raise ConfigError(
                "training runs on --executor local (SB3; --envs already steps envs in local processes) or ray (RLlib)"
            )
        if ex == "ray" and algo not in ("ppo", "ppo_et"):
            raise ConfigError(f"--executor ray trains ppo and ppo_et on RLlib; train {algo} with --executor local")
        if demos is not None and not (demos / "data").is_dir():
            raise ConfigError(
                f"no demonstration dataset at {demos}; collect one with `curbside demos collect --task {task} --out DIR` "
                "and pass the folder it prints"
            )
        if algo in ("iql", "td3bc", "bc", "gail") and demos is None:
            raise ConfigError(
                f"{algo} learns from demonstrations: pass --demos DIR (collect with `curbside demos collect --task {task}`)"
            )
        if init_from is not None:
            if algo not in ("ppo", "ppo_lag", "ppo_et"):
                raise ConfigError(f"--init-from fine-tunes PPO, PPO-Lag and PPO-ET; {algo} starts from scratch")
            check_init_from(init_from, algo, task, r["env_config"], r["hparams"]["net_arch"])
        _check_env_config(task, r["env_config"], split)
    except (ConfigError, ValueError, FileNotFoundError) as e:
        raise fail(str(e)) from None
    for s in seed_list:
        run_out = out / f"seed_{s}" if seeds is not None else out
        path = train(
            algo,
            task,
            run_out,
            steps=steps,
            protocol=protocol,
            backend=backend,
            split=split,
            env_config=cfg,
            n_envs=envs,
            num_scenes=scenes,
            seed=s,
            demos=demos,
            resume=resume,
            init_from=init_from,
            eval_every=eval_every,
            eval_episodes=eval_episodes,
            hparams=overrides,
            executor=ex,
            num_env_runners=num_env_runners,
            address=address,
        )
        Console(stderr=True).print(
            f"[green]trained[/] {algo} on {task} ({protocol}, {split}, seed {s}): {path}", highlight=False
        )
    if seeds is not None:
        from curbside.train.seeds import aggregate_seeds

        summary = aggregate_seeds(out, seed_list)
        typer.echo(json.dumps(summary, sort_keys=True))


def _parse_seeds(text: str) -> list[int]:
    """`--seeds 0,1,2` as distinct non-negative integers."""
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ConfigError(f"--seeds must be comma-separated integers such as 0,1,2, got {text!r}") from None
    if not values or min(values) < 0 or len(set(values)) != len(values):
        raise ConfigError(f"--seeds must be distinct integers >= 0 such as 0,1,2, got {text!r}")
    return values


@app.command("ppo")
def ppo_cmd(
    task: str = typer.Option("PointNav", help="PointNav or SocialNav."),
    out: Path = typer.Option(Path("outputs/train/ppo"), help="Output folder: run.json, policy, checkpoints, logs."),
    steps: int = typer.Option(200_000, min=1, help="Env steps."),
    envs: int | None = typer.Option(
        defaults.RUN_N_ENVS, min=1, max=256, help="Parallel envs (in all); default: the protocol's (8)."
    ),
    scenes: int | None = typer.Option(
        defaults.RUN_NUM_SCENES,
        min=1,
        help="Train-split scenes, sharded across the workers or env runners; default: 64.",
    ),
    seed: int = typer.Option(defaults.RUN_SEED, min=0, help="Seed of the run."),
    resume: bool = typer.Option(False, help="Continue from the latest checkpoint in --out."),
    eval_every: int = typer.Option(
        defaults.RUN_EVAL_EVERY, min=0, help="Evaluate on the test split every N env steps (0: never)."
    ),
    config: str | None = typer.Option(None, help="Env config overrides as a JSON object."),
    executor: Executor = typer.Option("local", help="local (SB3) or ray (RLlib PPO on a Ray cluster)."),
    num_env_runners: int = typer.Option(2, "--num-env-runners", min=1, max=1024, help="RLlib env runners (ray)."),
    address: str | None = address_option(),
) -> None:
    """Train PPO (`train run --algo ppo`); with --executor ray on RLlib, env runners spread over the cluster."""
    run_cmd(
        algo="ppo",
        task=task,
        out=out,
        steps=steps,
        demos=None,
        envs=envs,
        scenes=scenes,
        seed=seed,
        resume=resume,
        eval_every=eval_every,
        config=config,
        executor=executor,
        num_env_runners=num_env_runners,
        address=address,
        protocol="curbside",
        backend="pybullet",
        split="train",
        init_from=None,
        seeds=None,
        eval_episodes=None,
        hparams=None,
    )


@app.command("eval")
def eval_cmd(
    run_dir: Path = typer.Argument(..., help="A folder written by `curbside train run`."),
    split: str = typer.Option("test", help="train, test, unseen or finetune."),
    episodes: int | None = typer.Option(
        None,
        min=1,
        help="Episodes (seeds seed..seed+N-1); default: the run's protocol's (curbside 50, paper and "
        "paper_realistic 200).",
    ),
    seed: int = typer.Option(0, min=0, help="Seed of the first episode."),
    config: str | None = typer.Option(
        None,
        help="Env config overrides as a JSON object (default: the run's, with its protocol's episode rules for "
        "evaluations).",
    ),
    workers: int = typer.Option(
        1, min=1, max=64, help="Processes sharing the episodes (the same figures for any count)."
    ),
    actions: str | None = typer.Option(
        None,
        help="mean (the policy's mean action) or sampled (drawn from its distribution, as MetaUrban's evaluation "
        "script does; PPO family, BC and GAIL); default: the run's protocol's rule (curbside mean, paper and "
        "paper_realistic sampled).",
    ),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Evaluate a trained policy on a split: SR, SPL, SNS (SocialNav), Cost."""
    require("train", "train eval")
    from curbside.train.evaluate import EVAL_ACTIONS, evaluate_run
    from curbside.train.policies import eval_actions_of, load_policy, read_run
    from curbside.train.protocols import deep_merge
    from curbside.train.protocols import protocol as get_protocol

    try:
        if actions is not None and actions not in EVAL_ACTIONS:
            raise ConfigError(f"unknown --actions {actions!r}; valid: {', '.join(EVAL_ACTIONS)}")
        run = read_run(run_dir)
        proto = get_protocol(run.get("protocol", "curbside"))
        actions = actions or eval_actions_of(run, proto.eval_actions)
        # A run that cannot be loaded (or cannot sample) fails here, before any worker starts.
        load_policy(run_dir, deterministic=actions == "mean")
        # The protocol's episode rules for evaluations first; the user's overrides win.
        cfg = deep_merge(deep_merge(run.get("env_config", {}), proto.eval_env), parse_config_json(config))
        _check_env_config(run["task"], cfg, split)
    except (ConfigError, ValueError, FileNotFoundError) as e:
        raise fail(str(e)) from None
    episodes = episodes or proto.eval_episodes
    summary = evaluate_run(
        run_dir,
        run["task"],
        cfg,
        split=split,
        episodes=episodes,
        seed=seed,
        progress=not as_json,
        num_scenes=proto.eval_scenes,
        workers=workers,
        actions=actions,
    )
    summary["algo"] = run["algo"]
    if as_json:
        typer.echo(json.dumps(summary, sort_keys=True))
        return
    sns = f"  SNS {summary['sns']:.3f}" if "sns" in summary else ""
    typer.echo(
        f"{run['algo']} on {run['task']} {split}, {episodes} episodes: SR {summary['sr']:.3f}  "
        f"SPL {summary['spl']:.3f}{sns}  Cost {summary['cost']:.2f}  ({actions} actions)"
    )


@demos_app.command("collect")
def collect_cmd(
    task: str = typer.Option("PointNav", help="PointNav or SocialNav."),
    out: Path | None = typer.Option(
        None,
        help="Minari datasets root (default: Minari's, MINARI_DATASETS_PATH or "
        "~/.minari/datasets); the dataset goes to OUT/curbside/<task>-expert-v0.",
    ),
    steps: int = typer.Option(defaults.DEMOS_STEPS, min=1, max=10_000_000, help="Steps to record (whole episodes)."),
    noise: float = typer.Option(
        defaults.DEMOS_NOISE, min=0.0, max=5.0, help="Std of the Gaussian noise added to the expert's actions."
    ),
    random_prob: float = typer.Option(
        defaults.DEMOS_RANDOM_PROB, min=0.0, max=1.0, help="Fraction of fully random episodes."
    ),
    policy: Path | None = typer.Option(
        None,
        help="A trained PPO-family run of the task: drives --policy-fraction "
        "of the episodes (the paper: 80 % from a trained PPO policy).",
    ),
    policy_fraction: float = typer.Option(0.0, min=0.0, max=1.0, help="Fraction of episodes driven by --policy."),
    scenes: int = typer.Option(defaults.DEMOS_NUM_SCENES, min=1, help="Train-split scenes to draw episodes from."),
    seed: int = typer.Option(defaults.DEMOS_SEED, min=0, help="Seed of the first episode."),
    config: str | None = typer.Option(None, help="Env config overrides as a JSON object."),
    executor: Executor = executor_option(),
    workers: int | None = workers_option(),
    address: str | None = address_option(),
) -> None:
    """Record the noisy expert on the train split as a Minari dataset; print its path and success rate.

    Episodes can run on a process pool or a Ray cluster (--executor): episode k depends on (seed, k) alone and
    the dataset keeps episodes in index order, so every executor writes the same dataset."""
    require("train", "demos collect")
    from curbside.train.demos import collect_demos, minari_root

    cfg = parse_config_json(config)
    ex = check_executor_args(executor, address)
    try:
        _check_env_config(task, cfg, "train")
        if policy_fraction > 0 and policy is None:
            raise ConfigError("--policy-fraction needs --policy RUN (a trained PPO run of the task)")
        if policy is not None:
            from curbside.train.online import check_init_from

            check_init_from(policy, "ppo", task, cfg)
    except (ConfigError, ValueError, FileNotFoundError) as e:
        raise fail(str(e)) from None
    root = minari_root() if out is None else out
    summary = collect_demos(
        task,
        root,
        steps=steps,
        noise=noise,
        random_prob=random_prob,
        env_config=cfg,
        num_scenes=scenes,
        seed=seed,
        executor=ex,
        workers=workers,
        address=address,
        policy=policy,
        policy_fraction=policy_fraction,
    )
    typer.echo(
        f"{summary['path']}: {summary['episodes']} episodes, {summary['steps']} steps, "
        f"success rate {summary['success_rate']:.2f}"
    )
    env_prefix = "" if Path(root).resolve() == minari_root().resolve() else f"MINARI_DATASETS_PATH={root} "
    typer.echo(f"load it with: {env_prefix}python -c \"import minari; minari.load_dataset('{summary['dataset_id']}')\"")
