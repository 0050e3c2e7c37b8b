"""The CLI's option defaults are the declared ones, and reading them keeps `curbside --help` light.

Each default that an option shares with the code it drives is declared once, in a module that imports nothing
heavy (sim.tasks, sim.tasks.pointnav, sim.tasks.sensors, sim.scene.config, curbside.train.defaults,
retrieval.defaults); the function takes it as its keyword default and the option shows it. These tests check both
ends against the declaration, and that importing the CLI loads none of pybullet, torch, duckdb or transformers."""

from __future__ import annotations

import inspect
import json
import subprocess
import sys
from typing import Any

import pytest
import typer.main

from curbside.cli import catalog, scenes, sim, train

HEAVY = ("pybullet", "torch", "duckdb", "transformers")


def _default(app: typer.Typer, command: str, option: str) -> Any:
    """The default of `--option` of `command` in `app`, as click sees it (enum values unwrapped)."""
    group = typer.main.get_command(app)
    # an app with one command is that command itself (typer flattens it)
    cmd = group.commands[command] if hasattr(group, "commands") else group
    (param,) = [p for p in cmd.params if p.name == option]
    value = param.default
    return getattr(value, "value", value)


def _kwdefault(fn: Any, name: str) -> Any:
    """The default of keyword argument `name` of `fn`."""
    return inspect.signature(fn).parameters[name].default


def _heavy_modules_after(code: str) -> list[str]:
    """The HEAVY modules loaded by running `code` in a fresh interpreter."""
    probe = f"import sys\n{code}\nimport json; print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_importing_the_cli_loads_nothing_heavy() -> None:
    assert _heavy_modules_after("import curbside.cli.main") == []


def test_help_loads_nothing_heavy() -> None:
    # every group's --help: click builds each command's options (and so reads every default) to print them
    code = (
        "import typer.main\n"
        "from curbside.cli.main import app\n"
        "cli = typer.main.get_command(app)\n"
        "for args in ([], ['catalog'], ['scenes'], ['sim'], ['pool'], ['train'], ['demos'], ['experiment'],\n"
        "             ['sim', 'bench'], ['train', 'run'], ['demos', 'collect'], ['catalog', 'ingest']):\n"
        "    try:\n"
        "        cli.main([*args, '--help'], prog_name='curbside', standalone_mode=False)\n"
        "    except SystemExit:\n"
        "        pass"
    )
    assert _heavy_modules_after(code) == []


def test_the_default_declarations_are_light() -> None:
    modules = ("sim.tasks", "sim.tasks.pointnav", "sim.tasks.sensors", "sim.scene.config")
    modules += ("curbside.train.defaults", "retrieval.defaults")
    assert _heavy_modules_after("\n".join(f"import {m}" for m in modules)) == []


def test_scene_options_are_the_generator_defaults() -> None:
    from sim.scene.config import DEFAULT_CONFIG, PRESETS
    from sim.scene.dataset import build_dataset

    for command in ("generate", "dataset"):
        assert int(_default(scenes.app, command, "blocks")) == DEFAULT_CONFIG["blocks"]
        assert _default(scenes.app, command, "object_density") == DEFAULT_CONFIG["object_density"]
        assert _default(scenes.app, command, "terrain_density") == DEFAULT_CONFIG["terrain"]["density"]
    assert _default(scenes.app, "generate", "templates") == DEFAULT_CONFIG["templates"]
    assert _default(scenes.app, "generate", "crosswalk_density") == DEFAULT_CONFIG["crosswalk_density"]
    assert _default(scenes.app, "generate", "country") == DEFAULT_CONFIG["country"]
    assert _default(scenes.app, "dataset", "preset") in PRESETS
    assert _default(scenes.app, "dataset", "workers") == _kwdefault(build_dataset, "workers")


def test_ingest_options_are_the_declared_retrieval_defaults() -> None:
    from retrieval import defaults
    from retrieval.render import MAX_VIEWS
    from retrieval.scoring import ScoringConfig
    from retrieval.sources.procedural import ProceduralSource

    assert _default(catalog.app, "ingest", "views") == defaults.DEFAULT_N_VIEWS
    assert MAX_VIEWS == defaults.MAX_VIEWS
    for command in ("ingest", "eval"):
        assert _default(catalog.app, command, "scorer") == defaults.DEFAULT_IMAGE_ENCODER
        assert _default(catalog.app, command, "calibration") == defaults.DEFAULT_CALIBRATION
        assert _default(catalog.app, command, "thresholds") == defaults.DEFAULT_THRESHOLDS
    scoring = ScoringConfig()
    assert (scoring.image_encoder, scoring.calibration, scoring.thresholds) == (
        defaults.DEFAULT_IMAGE_ENCODER,
        defaults.DEFAULT_CALIBRATION,
        defaults.DEFAULT_THRESHOLDS,
    )
    assert _default(catalog.app, "ingest", "per_category") == defaults.DEFAULT_PER_CATEGORY
    assert _kwdefault(ProceduralSource.__init__, "per_category") == defaults.DEFAULT_PER_CATEGORY


def test_ingest_config_views_is_the_declared_default() -> None:
    pytest.importorskip("trimesh")  # retrieval.pipeline imports it
    from retrieval import defaults
    from retrieval.pipeline import IngestConfig

    assert IngestConfig().n_views == defaults.DEFAULT_N_VIEWS


def test_bench_options_are_the_task_and_camera_defaults() -> None:
    from sim.bench import run_bench, run_camera_bench
    from sim.camera import CAMERA_DEFAULTS as CAMERA_DEFAULTS_OF_SIM_CAMERA
    from sim.tasks import DEFAULT_TASK
    from sim.tasks.pointnav import DEFAULT_CONFIG
    from sim.tasks.sensors import CAMERA_DEFAULTS

    assert CAMERA_DEFAULTS_OF_SIM_CAMERA is CAMERA_DEFAULTS
    for fn in (run_bench, run_camera_bench):
        assert _kwdefault(fn, "machine") == DEFAULT_CONFIG["machine"]
        assert _kwdefault(fn, "task") == DEFAULT_TASK
    assert _default(sim.app, "bench", "machine") == DEFAULT_CONFIG["machine"]
    assert _default(sim.app, "bench", "task") == DEFAULT_TASK
    assert _default(sim.app, "bench", "size") == _kwdefault(run_camera_bench, "size") == CAMERA_DEFAULTS["width"]
    assert CAMERA_DEFAULTS["height"] == CAMERA_DEFAULTS["width"]  # --size is both
    assert (
        _default(sim.app, "bench", "renderer")
        == _kwdefault(run_camera_bench, "renderer")
        == CAMERA_DEFAULTS["renderer"]
    )


def test_train_options_are_the_declared_run_and_collect_defaults() -> None:
    from curbside.train import defaults
    from curbside.train.demos import collect_demos
    from curbside.train.run import train as run_train

    run = {"n_envs": defaults.RUN_N_ENVS, "num_scenes": defaults.RUN_NUM_SCENES, "seed": defaults.RUN_SEED}
    run["eval_every"] = defaults.RUN_EVAL_EVERY
    options = {"n_envs": "envs", "num_scenes": "scenes", "seed": "seed", "eval_every": "eval_every"}
    for name, value in run.items():
        assert _kwdefault(run_train, name) == value
        for command in ("run", "ppo"):
            assert _default(train.app, command, options[name]) == value
    collect = {
        "steps": defaults.DEMOS_STEPS,
        "noise": defaults.DEMOS_NOISE,
        "random_prob": defaults.DEMOS_RANDOM_PROB,
        "num_scenes": defaults.DEMOS_NUM_SCENES,
        "seed": defaults.DEMOS_SEED,
    }
    for name, value in collect.items():
        assert _kwdefault(collect_demos, name) == value
        option = "scenes" if name == "num_scenes" else name
        assert _default(train.demos_app, "collect", option) == value
