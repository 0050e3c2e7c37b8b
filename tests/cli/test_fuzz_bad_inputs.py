"""Fuzz: hundreds of generated bad inputs through the `curbside` CLI and the env API.

Every bad CLI input must end in exactly one stderr line `error: ...` with exit code 1 or 2 (no traceback, no
hang), must not touch the catalog it was pointed at, and must not leave a new catalog behind. Every bad env
config must raise ConfigError at construction (a good-looking value that is accepted must give finite
observations).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import typer

from curbside.cli.errors import run
from curbside.cli.main import app
from kernel.config import ConfigError

COMMAND = typer.main.get_command(app)


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A small real catalog, a real scene, and the kinds of broken files users hand over."""
    root = tmp_path_factory.mktemp("fuzz")
    catalog = root / "good.duckdb"
    assert (
        run(
            COMMAND,
            [
                "catalog",
                "build",
                "--catalog",
                str(catalog),
                "--variants",
                "1",
                "--category",
                "bench",
                "--category",
                "trash_bin",
            ],
        )
        == 0
    )
    garbage = root / "garbage.bin"
    garbage.write_bytes(np.random.default_rng(0).bytes(4096))
    empty = root / "empty.duckdb"
    empty.write_bytes(b"")
    truncated = root / "truncated.duckdb"
    truncated.write_bytes(catalog.read_bytes()[: catalog.stat().st_size // 3])
    listing = root / "list.json"
    listing.write_text("[1, 2, 3]")
    obj = root / "obj.json"
    obj.write_text("{}")
    import warnings

    from sim.scene import generate_scene

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # default-size boxes: no catalog needed for a broken scene
        spec = generate_scene({"blocks": 1, "object_density": 0.5}, 0)
    spec["objects"][0]["position"][0] = math.nan
    nan_scene = root / "nan_scene.json"
    nan_scene.write_text(json.dumps(spec))
    empty_dir = root / "empty_dir"
    empty_dir.mkdir()
    return {
        "root": root,
        "catalog": catalog,
        "garbage": garbage,
        "empty": empty,
        "truncated": truncated,
        "list": listing,
        "obj": obj,
        "nan_scene": nan_scene,
        "dir": empty_dir,
        "missing": root / "missing.json",
    }


def _cases(f: dict[str, Path]) -> list[list[str]]:
    """The bad inputs: each a full argv of one `curbside` command."""
    cat = ["--catalog", str(f["catalog"])]
    bad_paths = [f["missing"], f["dir"], f["garbage"], f["empty"], f["truncated"], f["list"]]
    cases: list[list[str]] = []
    # Catalog commands on broken catalog files.
    for p in bad_paths:
        c = ["--catalog", str(p)]
        cases += [
            ["catalog", "query", "bench", *c],
            ["catalog", "stats", *c],
            ["catalog", "show", "x", *c],
            ["catalog", "export", *c, "--out", str(f["root"] / "export.parquet")],
        ]
    cases += [["catalog", "validate", "--catalog", str(p)] for p in (f["missing"], f["dir"])]
    # Catalog commands with bad options on a good catalog.
    cases += [["catalog", "query", "bench", *cat, "--limit", v] for v in ("0", "-3", "abc", "1.5")]
    cases += [["catalog", "query", "bench", *cat, "--object-class", v] for v in ("bogus", "")]
    cases += [["catalog", "query", "bench", *cat, "--zone", v] for v in ("road", "x")]
    cases += [["catalog", "query", "bench", *cat, "--max-height", v] for v in ("abc", "nan", "-1", "inf")]
    cases += [["catalog", "show", "no-such-asset", *cat], ["catalog", "query", *cat]]
    cases += [["catalog", "export", *cat, "--format", v] for v in ("xml", "")]
    cases += [["catalog", "export", *cat, "--out", str(f["dir"])]]
    cases += [
        ["catalog", "build", "--catalog", str(f["root"] / "new.duckdb"), "--variants", v] for v in ("0", "-1", "x")
    ]
    cases += [["catalog", "build", "--catalog", str(f["root"] / "new.duckdb"), "--category", "spaceship"]]
    ingest = ["catalog", "ingest", "--catalog", str(f["root"] / "ingested.duckdb")]
    cases += [[*ingest, "--views", v] for v in ("0", "21", "-1", "abc", "1000")]
    cases += [[*ingest, "--executor", v] for v in ("bogus", "")]
    cases += [[*ingest, "--source", v] for v in ("bogus", f"local:{f['missing']}", f"local:{f['garbage']}", "http://x")]
    cases += [[*ingest, opt, "0"] for opt in ("--limit", "--workers", "--per-category")]
    cases += [
        [*ingest, "--scorer", "bogus"],
        [*ingest, "--calibration", "bogus"],
        [*ingest, "--scorer", "clip", "--clip-model", str(f["missing"])],
    ]
    # Scenes.
    gen = ["scenes", "generate"]
    cases += [[*gen, "--blocks", v] for v in ("0", "-1", "100000", "abc", "SQX", "", "65", "1.5")]
    cases += [[*gen, "--object-density", v] for v in ("nan", "inf", "-inf", "-1", "1e6", "abc", "")]
    cases += [[*gen, "--crosswalk-density", v] for v in ("nan", "2", "-0.1", "x")]
    cases += [[*gen, "--terrain-density", v] for v in ("nan", "-1", "11")]
    cases += [[*gen, "--seed", v] for v in ("-5", "abc", "1e99")]
    cases += [[*gen, "--templates", v] for v in ("z", "", "ab9")]
    cases += [
        [*gen, "--out", str(f["dir"])],
        [*gen, "--catalog", str(f["garbage"])],
        [*gen, "--catalog", str(f["missing"])],
    ]
    for p in (f["missing"], f["dir"], f["garbage"], f["list"], f["obj"], f["nan_scene"]):
        cases.append(["scenes", "render", str(p), "--out", str(f["root"] / "r.png")])
    cases += [["scenes", "render", str(f["nan_scene"]), "--dpi", v] for v in ("0", "-1", "abc", "5000")]
    ds = ["scenes", "dataset", "--out", str(f["root"] / "ds")]
    cases += [[*ds, "--count", v] for v in ("0", "-5", "abc")]
    cases += [
        [*ds, "--split", "bogus"],
        [*ds, "--workers", "0"],
        [*ds, "--blocks", "0"],
        [*ds, "--object-density", "nan"],
        [*ds, "--preset", "bogus"],
        [*ds, "--catalog", str(f["garbage"])],
    ]
    cases += [["scenes", "stats", str(p)] for p in (f["missing"], f["garbage"], f["dir"])]
    # Simulator.
    configs = [
        '{"bogus": 1}',
        "{bad",
        "[1, 2]",
        '{"dt": NaN}',
        '{"dt": -1}',
        '{"horizon": "abc"}',
        '{"num_waypoints": -3}',
        '{"lidar": {"range": NaN}}',
        '{"lidar": 5}',
        '"text"',
        "null",
        '{"reward_preset": "x"}',
        '{"machine": "tank"}',
        '{"lidar": {"beams": 0}}',
        '{"dt": Infinity}',
    ]
    for cmd in (["sim", "eval", "--episodes", "1"], ["sim", "rollout", "--out", str(f["root"] / "r.gif")]):
        cases += [[*cmd, "--config", c] for c in configs]
        cases += [
            [*cmd, "--machine", "tank"],
            [*cmd, "--seed", "-1"],
            [*cmd, "--task", "Fly"],
            [*cmd, "--policy", "magic"],
        ]
        cases += [
            [*cmd, "--scene-path", str(p)]
            for p in (f["missing"], f["dir"], f["garbage"], f["list"], f["obj"], f["nan_scene"])
        ]
    cases += [["sim", "eval", "--episodes", v] for v in ("0", "-1", "x")]
    cases += [["sim", "bench", "--machine", "tank"], ["sim", "bench", "--task", "Fly"]]
    # Pool.
    cases += [["pool", "show", "--pool", str(p)] for p in (f["missing"], f["garbage"], f["dir"])]
    cases += [["pool", "show", "--top", v] for v in ("0", "-1")]
    # Training and demonstrations.
    out = str(f["root"] / "run")
    tr = ["train", "run", "--out", out, "--steps", "8"]
    cases += [[*tr, "--algo", v] for v in ("bogus", "")]
    cases += [
        [*tr, "--task", "Fly"],
        [*tr, "--config", "{bad"],
        [*tr, "--config", '{"bogus": 1}'],
        [*tr, "--algo", "iql"],
        [*tr, "--algo", "bc", "--demos", str(f["missing"])],
        [*tr, "--envs", "0"],
        [*tr, "--scenes", "0"],
        ["train", "run", "--out", out, "--steps", "0"],
    ]
    cases += [["train", "eval", str(p)] for p in (f["missing"], f["garbage"], f["dir"])]
    cases += [["train", "eval", str(f["dir"]), "--split", "bogus"]]
    dm = ["demos", "collect", "--out", str(f["root"] / "demos")]
    cases += [[*dm, "--noise", v] for v in ("nan", "-1", "9")]
    cases += [[*dm, "--steps", "0"], [*dm, "--task", "Fly"], [*dm, "--config", "{bad"], [*dm, "--random-prob", "2"]]
    cases += [
        ["sim", "rollout", "--out", str(f["dir"])],
        ["sim", "rollout", "--out", str(f["root"] / "r.gif"), "--metrics-out", str(f["dir"])],
        ["train", "eval", str(f["dir"]), "--episodes", "0"],
    ]
    cases += [["bogus"], ["catalog", "bogus"], ["sim", "eval", "--bogus"]]
    return cases


def test_hundreds_of_bad_cli_inputs_end_in_one_error_line(files: dict[str, Path], capfd: pytest.CaptureFixture) -> None:
    cases = _cases(files)
    assert len(cases) >= 200
    before = _digest(files["catalog"])
    capfd.readouterr()
    bad: list[str] = []
    for argv in cases:
        code = run(COMMAND, argv)
        out, err = capfd.readouterr()
        lines = [ln for ln in err.splitlines() if ln.strip()]
        # Bad input exits 2 with a message of its own: not the catch-all for unexpected errors (exit 1, "rerun
        # with --debug"), nor a bare exception text such as a KeyError's quoted key.
        ok = (
            code == 2
            and len(lines) == 1
            and lines[0].startswith("error: ")
            and "Traceback" not in out + err
            and "rerun with --debug" not in lines[0]
            and not re.fullmatch(r"error: '[^']*'", lines[0])
        )
        if not ok:
            bad.append(f"{' '.join(argv)!r}: exit {code}, stderr {lines[:3]}")
    # `validate` reports a damaged catalog as its finding (a table, exit 1) rather than an error line.
    for p in (files["garbage"], files["empty"], files["truncated"]):
        code = run(COMMAND, ["catalog", "validate", "--catalog", str(p)])
        out, err = capfd.readouterr()
        if code != 1 or "Traceback" in out + err or p.name not in "".join(out.split()):
            bad.append(f"validate {p.name}: exit {code}, stdout {out[-300:]!r}, stderr {err[-300:]!r}")
    assert not bad, f"{len(bad)} of {len(cases)} bad inputs misbehaved:\n" + "\n".join(bad)
    assert _digest(files["catalog"]) == before, "a bad input changed the catalog it was pointed at"
    assert run(COMMAND, ["catalog", "validate", "--catalog", str(files["catalog"])]) == 0
    for leftover in ("ingested.duckdb", "new.duckdb"):
        assert not (files["root"] / leftover).exists(), f"a failed run left {leftover} behind"


BAD_VALUES = [math.nan, math.inf, -1, -1e9, "abc", None, [], {"x": 1}, True]


def _env_cases() -> list[tuple[str, str, object]]:
    from sim.tasks.pointnav import DEFAULT_CONFIG

    keys = [k for k in DEFAULT_CONFIG if k not in ("scene_spec", "scene_path", "scene_dir", "machine_config")]
    return [(env, k, v) for env in ("curbside/PointNav-v0",) for k in keys for v in BAD_VALUES]


def test_bad_env_configs_fail_at_construction_or_run_finite() -> None:
    import sim  # noqa: F401  (registers the envs)

    cases = _env_cases()
    assert len(cases) >= 200
    accepted, wrong = [], []
    for env_id, key, value in cases:
        try:
            env = gym.make(env_id, config={"num_scenes": 1, "scene": {"blocks": 1}, key: value})
        except ConfigError as e:
            if key not in str(e):
                wrong.append(f"{key}={value!r}: message does not name the key: {e}")
            continue
        except Exception as e:  # noqa: BLE001 (any other exception type is the defect under test)
            wrong.append(f"{key}={value!r}: {type(e).__name__}: {e}")
            continue
        accepted.append((key, value))
        try:
            obs, _ = env.reset(seed=0)
            obs, reward, *_ = env.step(env.action_space.sample())
            if not (np.all(np.isfinite(obs)) and np.isfinite(reward)):
                wrong.append(f"{key}={value!r}: accepted but gives non-finite observations or reward")
        except Exception as e:  # noqa: BLE001
            wrong.append(f"{key}={value!r}: accepted at construction, then {type(e).__name__} at reset/step: {e}")
        finally:
            env.close()
    assert not wrong, f"{len(wrong)} of {len(cases)} bad env configs misbehaved:\n" + "\n".join(wrong)
    assert len(accepted) < len(cases) // 4, f"too many bad values accepted: {accepted[:20]}"
