"""`curbside sim`: Run, evaluate, render and benchmark the PyBullet simulator."""

from __future__ import annotations

import json
from enum import Enum
from pathlib import Path
from typing import TypedDict

import typer

from curbside.cli.errors import UsageError, parse_config_json
from curbside.cli.executor_options import (
    Executor,
    address_option,
    check_executor_args,
    executor_option,
    workers_option,
)

# The declarations sim.bench's keyword defaults read (light modules, no pybullet): the bench options show them.
from sim.tasks import DEFAULT_TASK
from sim.tasks.pointnav import DEFAULT_CONFIG as POINTNAV_DEFAULTS
from sim.tasks.sensors import CAMERA_DEFAULTS

app = typer.Typer(
    rich_markup_mode=None, help="Run, evaluate, render and benchmark the PyBullet simulator.", no_args_is_help=True
)

# Task names on the command line -> Gymnasium env ids (SocialNav is added by sim.envs.socialnav).
TASKS = {"PointNav": "curbside/PointNav-v0", "SocialNav": "curbside/SocialNav-v0"}
POLICIES = ("expert", "random")
# The names of sim.machines.MACHINES, listed here so `--help` does not import pybullet (a test keeps them equal).
MACHINE_NAMES = (
    "delivery_bot",
    "delivery_bot_mod1",
    "delivery_bot_mod2",
    "wheelchair",
    "mobility_scooter",
    "robot_dog",
    "humanoid",
    "metaurban_coco",
    "metaurban_coco_mod1",
    "metaurban_coco_mod2",
    "metaurban_wheelchair",
    "metaurban_scooter",
)
MAX_SEED = 2**31 - 1  # episode seeds seed..seed+N-1 must stay valid numpy seeds

Task = Enum("Task", {k: k for k in TASKS}, type=str)  # type: ignore[misc]
Policy = Enum("Policy", {k: k for k in POLICIES}, type=str)  # type: ignore[misc]
MachineName = Enum("MachineName", {k: k for k in MACHINE_NAMES}, type=str)  # type: ignore[misc]
Renderer = Enum("Renderer", {"tiny": "tiny", "egl": "egl"}, type=str)  # sim.camera renderers


class _PathChecks(TypedDict):
    """typer.Option's path checks, typed so mypy matches them to its keyword arguments."""

    exists: bool
    dir_okay: bool
    readable: bool


SCENE_PATH = _PathChecks(exists=True, dir_okay=False, readable=True)


def _env_config(machine: MachineName | None, scene_path: Path | None, config_json: str | None) -> dict:
    cfg = parse_config_json(config_json)
    if machine:
        cfg["machine"] = machine.value
    if scene_path:
        cfg["scene_path"] = str(scene_path)
    return cfg


def _check_env(env_id: str, cfg: dict) -> None:
    """Build the env once so a bad config or scene file fails as one line before any episode (or progress bar)."""
    import gymnasium as gym

    import sim  # noqa: F401  (registers the env ids; imports pybullet quietly)

    gym.make(env_id, config=cfg).close()


@app.command("eval")
def eval_cmd(
    task: Task = typer.Option("PointNav", help="Task to run."),
    policy: Policy = typer.Option("expert", help="expert (pure pursuit) or random."),
    episodes: int = typer.Option(10, min=1, max=100_000, help="Number of episodes."),
    machine: MachineName | None = typer.Option(None, help="Machine (default: the task's; a custom one via --config)."),
    seed: int = typer.Option(0, min=0, max=MAX_SEED, help="Seed of the first episode; episode k uses seed + k."),
    scene_path: Path | None = typer.Option(None, **SCENE_PATH, help="A scene spec JSON instead of generated scenes."),
    config: str | None = typer.Option(None, help="Extra env config as a JSON object."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
    out: Path | None = typer.Option(
        None,
        "--out",
        help="Also write the summary (metrics.json) and one row per episode (episodes.csv) into this folder.",
    ),
    executor: Executor = executor_option(),
    workers: int | None = workers_option(),
    address: str | None = address_option(),
) -> None:
    """Run a policy for N episodes and print SR, SPL, Cost (plus every other metric the env reports).

    Episodes can be sharded over processes or a Ray cluster (--executor); episode k's seed is seed + k whoever runs
    it, and the metrics are aggregated in seed order, so every executor prints and writes the same bytes."""
    from sim.eval import evaluate, write_eval

    if seed + episodes - 1 > MAX_SEED:
        raise UsageError(f"--seed + --episodes must stay <= {MAX_SEED + 1}; lower --seed")
    if out is not None and out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} is a file; give a folder for metrics.json and episodes.csv")
    ex = check_executor_args(executor, address)
    env_id = TASKS[task.value]
    cfg = _env_config(machine, scene_path, config)
    _check_env(env_id, cfg)
    summary = evaluate(
        env_id,
        policy.value,
        episodes,
        cfg,
        seed=seed,
        progress=not as_json,
        executor=ex,
        workers=workers,
        address=address,
    )
    if out is not None:
        write_eval(summary, out)
    if as_json:
        typer.echo(json.dumps(summary, sort_keys=True))
        return
    typer.echo(
        f"{task.value} {policy.value} over {summary['episodes']} episodes: "
        f"SR {summary['sr']:.3f}  SPL {summary['spl']:.3f}  Cost {summary['cost']:.2f}"
    )
    for k, v in sorted(summary.items()):
        if k not in ("sr", "spl", "cost", "episodes") and isinstance(v, float):
            typer.echo(f"  {k}: {v:.3f}")


@app.command("rollout")
def rollout_cmd(
    out: Path = typer.Option(
        Path("outputs/rollout.gif"), help="GIF to write (a .png next to it holds the last frame)."
    ),
    task: Task = typer.Option("PointNav", help="Task to run."),
    policy: Policy = typer.Option("expert", help="expert or random."),
    machine: MachineName | None = typer.Option(None, help="Machine (default: the task's)."),
    seed: int = typer.Option(0, min=0, max=MAX_SEED, help="Episode seed."),
    scene_path: Path | None = typer.Option(None, **SCENE_PATH, help="A scene spec JSON instead of a generated scene."),
    config: str | None = typer.Option(None, help="Extra env config as a JSON object."),
    chase: bool = typer.Option(True, help="Add the chase-camera view next to the map."),
    video: Path | None = typer.Option(
        None,
        "--video",
        help="Write an MP4 of the env's dashboard (chase view, map, "
        "camera panels, metrics) through Gymnasium's RecordVideo instead of the GIF.",
    ),
    metrics_out: Path | None = typer.Option(None, help="Also write the episode's metrics as JSON here."),
) -> None:
    """Run one episode and write an animated GIF: top-down map with route and trajectory (+ chase camera), or with
    --video an MP4 of the dashboard."""
    from sim.frames import rollout_gif, rollout_video

    for path, flag in ((out, "--out"), (video, "--video"), (metrics_out, "--metrics-out")):
        if path is not None and path.is_dir():
            raise UsageError(f"{flag} {path} is a directory; give a file path such as {path / 'rollout.gif'}")
    env_id = TASKS[task.value]
    cfg = _env_config(machine, scene_path, config)
    _check_env(env_id, cfg)
    if video is not None:
        if video.suffix.lower() != ".mp4":
            raise UsageError(f"--video {video} must end in .mp4")
        try:
            metrics = rollout_video(env_id, policy.value, video, cfg, seed=seed)
        except ValueError as e:
            raise UsageError(str(e)) from None
        out = video
    else:
        metrics = rollout_gif(env_id, policy.value, out, cfg, seed=seed, chase=chase)
    if metrics_out:
        metrics_out.parent.mkdir(parents=True, exist_ok=True)
        metrics_out.write_text(json.dumps(metrics, indent=2, sort_keys=True))
    typer.echo(
        f"wrote {out} (success {metrics['success']:.0f}, route completion {metrics['route_completion']:.2f}, "
        f"steps {metrics['steps']:.0f})"
    )


@app.command("bench")
def bench_cmd(
    quick: bool = typer.Option(False, "--quick", help="Smaller counts (seconds instead of minutes)."),
    task: Task = typer.Option(DEFAULT_TASK, "--task", help="PointNav, or SocialNav (20 agents + traffic)."),
    machine: MachineName = typer.Option(POINTNAV_DEFAULTS["machine"], help="Machine to drive."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
    cameras: bool = typer.Option(
        False,
        "--cameras",
        help="Steps/s with each ego-camera modality instead (rgb, depth, semantic, all three) beside no camera.",
    ),
    size: int = typer.Option(
        CAMERA_DEFAULTS["width"], "--size", min=8, max=2048, help="Camera width and height in pixels (--cameras)."
    ),
    renderer: Renderer = typer.Option(
        CAMERA_DEFAULTS["renderer"], "--renderer", help="tiny (CPU) or egl (GPU) (--cameras)."
    ),
) -> None:
    """Env steps per CPU-second in the ~150-object bench scene vs the raw PyBullet floor measured in the same run;
    reset and scene build time; RSS growth over resets on one scene and over new scenes. With --cameras: steps/s
    with RGB, depth and semantic images (beside the MetaUrban paper's 50 / 60 / 120 FPS for RGB / depth / LiDAR)."""
    import sim  # noqa: F401  (imports pybullet quietly)
    from sim.bench import run_bench, run_camera_bench

    if cameras:
        result = run_camera_bench(
            quick=quick, machine=machine.value, size=size, renderer=renderer.value, task=task.value
        )
    else:
        result = run_bench(quick=quick, machine=machine.value, task=task.value)
    if as_json:
        typer.echo(json.dumps(result, sort_keys=True))
        return
    for k, v in result.items():
        typer.echo(f"{k:>24}: {v:.4g}" if isinstance(v, float) else f"{k:>24}: {v}")


Device = Enum("Device", {k: k for k in ("keyboard", "gamepad", "wheel")}, type=str)  # type: ignore[misc]


@app.command("teleop")
def teleop_cmd(
    task: Task = typer.Option("PointNav", help="Task to drive."),
    device: Device = typer.Option(
        "keyboard",
        help="keyboard (arrows/WASD, R ends the episode, Esc stops), gamepad or wheel (the first pygame joystick).",
    ),
    mapping: Path | None = typer.Option(
        None,
        exists=True,
        dir_okay=False,
        help="JSON axis map over the device's "
        "preset (steer_axis, throttle_axis, brake_axis, invert_*, pedals, deadzone).",
    ),
    out: Path = typer.Option(
        Path("outputs/demos"), help="Minari datasets root; episodes go to OUT/curbside/<task>-teleop-v0."
    ),
    episodes: int | None = typer.Option(None, min=1, help="Stop after this many episodes (default: until Esc)."),
    machine: MachineName | None = typer.Option(None, help="Machine (default: the task's)."),
    seed: int = typer.Option(0, min=0, max=MAX_SEED, help="First episode's seed."),
    scene_path: Path | None = typer.Option(None, **SCENE_PATH, help="A scene spec JSON instead of a generated scene."),
    config: str | None = typer.Option(None, help="Extra env config as a JSON object."),
) -> None:
    """Drive a task by hand in a window (dashboard with live metrics) and record the episodes as a Minari dataset,
    the format of `curbside demos collect`. Needs a display (or xvfb-run) and `pip install 'curbside[viewer]'`."""
    from curbside.train.teleop import teleop

    env_id = TASKS[task.value]
    cfg = _env_config(machine, scene_path, config)
    _check_env(env_id, cfg)
    summary = teleop(
        task.value, out, device=device.value, mapping_file=mapping, env_config=cfg, episodes=episodes, seed=seed
    )
    typer.echo(
        f"wrote {summary['path']}: {summary['episodes']} episode(s), {summary['steps']} steps, success rate "
        f"{summary['success_rate']:.2f}"
    )
