"""Every CLI option whose default mirrors a config default agrees with it. The CLI reads its defaults from the
configs, except where the config module is heavy (pybullet, torch, duckdb): there it keeps literals, so `--help`
stays light, and this test is what keeps the two equal."""

from __future__ import annotations

import inspect
from typing import Any

import pytest
import typer.main

from curbside.cli import catalog, scenes, sim, train


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


def test_scene_options_match_the_generator_defaults() -> None:
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


def test_ingest_options_match_the_ingest_config() -> None:
    pytest.importorskip("duckdb")
    from retrieval.pipeline import IngestConfig
    from retrieval.scoring import ScoringConfig
    from retrieval.sources.procedural import ProceduralSource

    config = IngestConfig()
    assert _default(catalog.app, "ingest", "views") == config.n_views
    for command in ("ingest", "eval"):
        assert _default(catalog.app, command, "scorer") == ScoringConfig().image_encoder
        assert _default(catalog.app, command, "calibration") == ScoringConfig().calibration
    assert _default(catalog.app, "ingest", "per_category") == _kwdefault(ProceduralSource.__init__, "per_category")


def test_sim_options_match_the_task_defaults() -> None:
    from sim.bench import run_bench
    from sim.tasks.pointnav import DEFAULT_CONFIG

    assert _default(sim.app, "bench", "machine") == DEFAULT_CONFIG["machine"] == _kwdefault(run_bench, "machine")
    assert _default(sim.app, "bench", "task") == _kwdefault(run_bench, "task")
    from sim.bench import run_camera_bench
    from sim.camera import CAMERA_DEFAULTS

    assert _default(sim.app, "bench", "size") == _kwdefault(run_camera_bench, "size") == CAMERA_DEFAULTS["width"]
    assert (
        _default(sim.app, "bench", "renderer")
        == _kwdefault(run_camera_bench, "renderer")
        == CAMERA_DEFAULTS["renderer"]
    )


def test_train_options_match_the_trainer_defaults() -> None:
    from curbside.train.demos import collect_demos
    from curbside.train.run import train as run_train

    assert _default(train.app, "run", "envs") == _kwdefault(run_train, "n_envs")
    assert _default(train.app, "run", "scenes") == _kwdefault(run_train, "num_scenes")
    assert _default(train.app, "run", "seed") == _kwdefault(run_train, "seed")
    assert _default(train.app, "run", "eval_every") == _kwdefault(run_train, "eval_every")
    for option in ("steps", "noise", "random_prob", "seed"):
        assert _default(train.demos_app, "collect", option) == _kwdefault(collect_demos, option)
    assert _default(train.demos_app, "collect", "scenes") == _kwdefault(collect_demos, "num_scenes")
