"""`curbside sim`: Run, evaluate, render and benchmark the PyBullet simulator."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

app = typer.Typer(help="Run, evaluate, render and benchmark the PyBullet simulator.", no_args_is_help=True)

# Task names on the command line -> Gymnasium env ids (SocialNav is added by sim.envs.socialnav).
TASKS = {"PointNav": "curbside/PointNav-v0", "SocialNav": "curbside/SocialNav-v0"}
POLICIES = ("expert", "random")


def _env_config(machine: Optional[str], scene_path: Optional[Path], config_json: Optional[str]) -> dict:
    cfg: dict = json.loads(config_json) if config_json else {}
    if machine:
        cfg["machine"] = machine
    if scene_path:
        cfg["scene_path"] = str(scene_path)
    return cfg


def _check(task: str, policy: str) -> str:
    if task not in TASKS:
        raise typer.BadParameter(f"unknown task {task!r}; valid: {', '.join(TASKS)}")
    if policy not in POLICIES:
        raise typer.BadParameter(f"unknown policy {policy!r}; valid: {', '.join(POLICIES)}")
    return TASKS[task]


@app.command("eval")
def eval_cmd(
    task: str = typer.Option("PointNav", help=f"Task: {', '.join(TASKS)}."),
    policy: str = typer.Option("expert", help="expert (pure pursuit) or random."),
    episodes: int = typer.Option(10, min=1, help="Number of episodes."),
    machine: Optional[str] = typer.Option(None, help="Machine name (default: the task's)."),
    seed: int = typer.Option(0, help="Seed of the first episode; episode k uses seed + k."),
    scene_path: Optional[Path] = typer.Option(None, help="A scene spec JSON instead of generated scenes."),
    config: Optional[str] = typer.Option(None, help="Extra env config as a JSON object."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Run a policy for N episodes and print SR, SPL, Cost (plus every other metric the env reports)."""
    from sim.eval import evaluate

    env_id = _check(task, policy)
    summary = evaluate(env_id, policy, episodes, _env_config(machine, scene_path, config), seed=seed,
                       progress=not as_json)
    if as_json:
        typer.echo(json.dumps(summary, sort_keys=True))
        return
    typer.echo(f"{task} {policy} over {summary['episodes']} episodes: "
               f"SR {summary['sr']:.3f}  SPL {summary['spl']:.3f}  Cost {summary['cost']:.2f}")
    for k, v in sorted(summary.items()):
        if k not in ("sr", "spl", "cost", "episodes") and isinstance(v, float):
            typer.echo(f"  {k}: {v:.3f}")


@app.command("rollout")
def rollout_cmd(
    out: Path = typer.Option(Path("outputs/rollout.gif"), help="GIF to write (a .png next to it holds the last frame)."),
    task: str = typer.Option("PointNav", help=f"Task: {', '.join(TASKS)}."),
    policy: str = typer.Option("expert", help="expert or random."),
    machine: Optional[str] = typer.Option(None, help="Machine name."),
    seed: int = typer.Option(0, help="Episode seed."),
    scene_path: Optional[Path] = typer.Option(None, help="A scene spec JSON instead of a generated scene."),
    config: Optional[str] = typer.Option(None, help="Extra env config as a JSON object."),
    chase: bool = typer.Option(True, help="Add the chase-camera view next to the map."),
    metrics_out: Optional[Path] = typer.Option(None, help="Also write the episode's metrics as JSON here."),
) -> None:
    """Run one episode and write an animated GIF: top-down map with route and trajectory (+ chase camera)."""
    from sim.render import rollout_gif

    env_id = _check(task, policy)
    metrics = rollout_gif(env_id, policy, out, _env_config(machine, scene_path, config), seed=seed, chase=chase)
    if metrics_out:
        metrics_out.parent.mkdir(parents=True, exist_ok=True)
        metrics_out.write_text(json.dumps(metrics, indent=2, sort_keys=True))
    typer.echo(f"wrote {out} (success {metrics['success']:.0f}, route completion {metrics['route_completion']:.2f}, "
               f"steps {metrics['steps']:.0f})")


@app.command("bench")
def bench_cmd(
    quick: bool = typer.Option(False, "--quick", help="Smaller counts (seconds instead of a minute)."),
    machine: str = typer.Option("delivery_bot", help="Machine to drive."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """PointNav env steps/s in a 3-block, ~200-object scene vs the raw PyBullet floor; reset time; RSS growth."""
    from sim.bench import run_bench

    result = run_bench(quick=quick, machine=machine)
    if as_json:
        typer.echo(json.dumps(result, sort_keys=True))
        return
    for k, v in result.items():
        typer.echo(f"{k:>24}: {v:.4g}" if isinstance(v, float) else f"{k:>24}: {v}")
