"""Fuzz, round two: generated nested configs, reset options, lifecycle orders, YAML documents and kill points.

Each generator draws from a seeded RNG, so a failure names a case that reproduces. Expected: a ConfigError or
ValueError that names the problem (configs, options, YAML), a RuntimeError that says what to do (lifecycle), and
no loss after a kill (the previous dataset stays whole).
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401  (registers the envs)
from kernel.config import ConfigError, load_yaml
from sim.batched import BatchedPointNav
from sim.tasks.pointnav import MACHINE_TABLE

CFG = {"scene": {"blocks": 1}, "num_scenes": 1}
NUMBERS_BAD = [math.nan, math.inf, -math.inf, -1.0, -1e12, 1e12, "fast", None, True, [1.0, 2.0, 3.0], {"x": 1}]


def machine_cases() -> list[dict]:
    """Every numeric machine key with a bad value, at the top level, under `base`, and under `base.base`."""
    cases = []
    for key in MACHINE_TABLE:
        for value in NUMBERS_BAD:
            if MACHINE_TABLE[key].kind == "pair" and isinstance(value, list):
                continue  # [1, 2, 3] is not a pair, but [1e12...] cases cover pairs out of range
            for depth in range(3):
                machine: dict = {key: value}
                for _ in range(depth):
                    machine = {"base": machine}
                cases.append(machine)
    return cases


def test_nested_machine_configs_are_refused_naming_the_path() -> None:
    cases = machine_cases()
    assert len(cases) >= 400
    wrong = []
    for k, machine in enumerate(cases):
        maker = (lambda c: gym.make("curbside/PointNav-v0", config=c)) if k % 2 else (lambda c: BatchedPointNav(2, c))
        try:
            env = maker({**CFG, "machine": machine})
        except ConfigError as e:
            if "config.machine" not in str(e) or len(str(e)) > 400:
                wrong.append(f"{machine}: {e}")
            continue
        except Exception as e:  # noqa: BLE001 (the defect under test)
            wrong.append(f"{machine}: {type(e).__name__}: {e}")
            continue
        env.close()
        wrong.append(f"{machine}: accepted")
    assert not wrong, f"{len(wrong)} of {len(cases)}:\n" + "\n".join(wrong[:20])


def option_cases(rng: np.random.Generator) -> list[object]:
    points = [
        [math.nan, 1.0],
        [1.0, math.inf],
        "ab",
        [1.0],
        [1.0, 2.0, 3.0],
        [[1.0, 2.0], [3.0]],
        None,
        {"x": 1},
        [True, "x"],
        b"xy",
    ]
    cases: list[object] = [5, 1.5, "start", [1.0, 2.0], (1, 2), b"x", True, object()]
    cases += [{"start": p, "goal": [1.0, 1.0]} for p in points] + [{"start": [1.0, 1.0], "goal": p} for p in points]
    cases += [{"start": [1.0, 1.0]}, {"goal": [1.0, 1.0]}]
    for _ in range(20):
        key = "".join(rng.choice(list("abcdeSGoalrt_"), size=int(rng.integers(1, 8))))
        if key not in ("start", "goal"):
            cases.append({key: [1.0, 2.0]})
    return cases


def test_generated_reset_options_are_named_errors() -> None:
    cases = option_cases(np.random.default_rng(0))
    env = gym.make("curbside/PointNav-v0", config=CFG)
    envs = BatchedPointNav(2, CFG)
    wrong = []
    try:
        for options in cases:
            for target in (env, envs):
                try:
                    target.reset(seed=0, options=options)
                    wrong.append(f"{options!r}: accepted")
                except ValueError as e:
                    if "reset option" not in str(e):
                        wrong.append(f"{options!r}: {e}")
                except Exception as e:  # noqa: BLE001
                    wrong.append(f"{options!r}: {type(e).__name__}: {e}")
    finally:
        env.close()
        envs.close()
    assert len(cases) * 2 >= 90 and not wrong, "\n".join(wrong[:20])


OPS = ("reset", "step", "render", "scene", "close")


@pytest.mark.parametrize("seed", range(60))
def test_lifecycle_orders_give_clear_errors(seed: int) -> None:
    """A random order of calls against a model: closed refuses everything; step and scene need a reset."""
    rng = np.random.default_rng(seed)
    ops = [OPS[int(i)] for i in rng.integers(len(OPS), size=6)]
    env = gym.make(
        "curbside/PointNav-v0", config={**CFG, "render": {"width": 64, "height": 48}}, render_mode="rgb_array"
    ).unwrapped
    closed = reset = False
    for op in ops:
        try:
            if op == "reset":
                env.reset(seed=seed)
            elif op == "step":
                env.step([0.0, 0.3])
            elif op == "render":
                env.render()
            elif op == "scene":
                env.scene  # noqa: B018
            else:
                env.close()
        except RuntimeError as e:
            expected = "closed" if closed else "reset"
            assert expected in str(e), (ops, op, str(e))
            assert closed or (not reset and op in ("step", "scene", "render")), (ops, op, str(e))
            continue
        assert op == "close" or not closed, (ops, op, "a closed env accepted a call")
        assert op in ("close", "reset", "render") or reset, (ops, op, "a never-reset env accepted a call")
        closed = closed or op == "close"
        reset = reset or op == "reset"
    env.close()


def yaml_cases(rng: np.random.Generator) -> list[str]:
    docs = []
    for n in range(3, 9):
        lines = [f"l0: &l0 [{', '.join(['x'] * n)}]"]
        lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * n)}]" for i in range(1, int(rng.integers(2, 9)))]
        docs.append("\n".join(lines))
    docs += [
        "a: [1, 2",
        "a: {b: 1",
        "- x\ny: 1",
        "a: 'x",
        "\t- tab",
        "a: !!python/object:os.system x",
        "? [a]\n: 1",
        "%YAML 9.9\n---\na: 1",
        "a: *undefined",
        "x: &x 1\ny: *x",
    ]
    for _ in range(24):
        docs.append("".join(rng.choice(list("[]{}:,'\"&*!|>-\n ab"), size=int(rng.integers(3, 40)))))
    return docs


def test_generated_yaml_parses_or_fails_in_one_short_line() -> None:
    docs = yaml_cases(np.random.default_rng(1))
    wrong = []
    for doc in docs:
        try:
            load_yaml(doc, "f.yaml")
        except ConfigError as e:
            if len(str(e)) > 300 or "f.yaml" not in str(e):
                wrong.append(f"{doc!r}: {str(e)[:200]}")
        except Exception as e:  # noqa: BLE001
            wrong.append(f"{doc!r}: {type(e).__name__}: {e}")
    assert len(docs) >= 40 and not wrong, "\n".join(wrong[:20])
    with pytest.raises(ConfigError, match="alias"):
        load_yaml(docs[0], "f.yaml")


@pytest.mark.slow
def test_a_killed_demos_collect_leaves_the_previous_dataset_whole(tmp_path: Path) -> None:
    import json

    import minari

    env = {**os.environ, "MINARI_DATASETS_PATH": str(tmp_path)}
    cfg = json.dumps({"scene": {"blocks": 1}, "route_length": [5.0, 25.0]})
    cmd = [
        sys.executable,
        "-m",
        "curbside.cli.main",
        "demos",
        "collect",
        "--steps",
        "60",
        "--scenes",
        "1",
        "--config",
        cfg,
    ]
    subprocess.run(cmd, env=env, check=True, capture_output=True, timeout=300)
    first = minari.MinariDataset(tmp_path / "curbside" / "pointnav-expert-v0" / "data").total_steps
    for delay in (1.0, 3.0, 5.0, 7.0, 9.0):
        proc = subprocess.Popen(
            [*cmd[:-4], "--steps", "400", *cmd[-4:]], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
        ds = minari.MinariDataset(tmp_path / "curbside" / "pointnav-expert-v0" / "data")
        assert ds.total_steps in (first, 400) or ds.total_steps >= 400, delay  # old whole, or the new one whole


def test_the_same_generators_through_the_cli_end_in_one_error_line(tmp_path: Path, capfd) -> None:
    """Nested machine configs (`sim eval --config`) and YAML documents (`scenes generate --from`) as a user types them:
    exit 2, one `error:` line, no traceback, nothing written."""
    import json

    import typer

    from curbside.cli.errors import run
    from curbside.cli.main import app

    command = typer.main.get_command(app)
    rng = np.random.default_rng(2)
    machines = machine_cases()
    argvs = []
    for k in rng.choice(len(machines), size=80, replace=False):
        cfg = json.dumps({"scene": {"blocks": 1}, "machine": machines[int(k)]})  # NaN / Infinity as JSON allows
        argvs.append(["sim", "eval", "--episodes", "1", "--config", cfg])
    for n, doc in enumerate(yaml_cases(np.random.default_rng(1))):
        f = tmp_path / f"custom_{n}.yaml"
        f.write_text(doc)
        argvs.append(["scenes", "generate", "--from", str(f), "--out", str(tmp_path / f"scene_{n}.json")])
    capfd.readouterr()
    bad = []
    for argv in argvs:
        code = run(command, argv)
        out, err = capfd.readouterr()
        lines = [ln for ln in err.splitlines() if ln.strip()]
        if not (code == 2 and len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in out + err):
            bad.append(f"{argv[-3:]}: exit {code}, {lines[:2]}")
    assert len(argvs) >= 120 and not bad, f"{len(bad)} of {len(argvs)}:\n" + "\n".join(bad[:15])
    assert not list(tmp_path.glob("scene_*.json"))


@pytest.mark.parametrize(
    "argv",
    [
        ["scenes", "dataset", "--split", "test", "--count", "1", "--out", ""],
        ["scenes", "generate", "--out="],
        ["sim", "eval", "--episodes", "1", "--out", ""],
        ["demos", "collect", "--task", "PointNav", "--steps", "50", "--out", ""],
        ["train", "run", "--algo", "ppo", "--task", "PointNav", "--steps", "64", "--out", ""],
    ],
)
def test_an_empty_option_value_is_refused_before_anything_is_written(argv, tmp_path, monkeypatch, capfd) -> None:
    """`--out ''` would mean the working directory: refused in one line, exit 2, and the folder stays empty."""
    import typer

    from curbside.cli.errors import run
    from curbside.cli.main import app

    monkeypatch.chdir(tmp_path)
    code = run(typer.main.get_command(app), argv)
    err = capfd.readouterr().err.strip().splitlines()
    assert code == 2 and err == [
        f"error: {argv[-1].rstrip('=') if argv[-1] else argv[-2]} is empty; give it a value (see the command's --help)"
    ]
    assert not list(tmp_path.iterdir())
