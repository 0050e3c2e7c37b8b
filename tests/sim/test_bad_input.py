"""Bad input on the simulator and scene side fails at once, as one line naming the problem and the fix.

CLI paths go through `curbside.cli.errors.run` (what the console script runs) or a real `curbside` process where
the process matters (pybullet's banner, stdout kept clean); env and scene configs fail at construction with the
valid range in the message.
"""

from __future__ import annotations

import copy
import json
import math
import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import gymnasium as gym
import pytest

import sim  # noqa: F401  (registers the env ids)
from kernel.config import ConfigError
from tests.helpers import cli, one_error_line

REPO = Path(__file__).resolve().parents[2]
CURBSIDE = Path(sys.executable).with_name("curbside")
POINTNAV = "curbside/PointNav-v0"
SOCIALNAV = "curbside/SocialNav-v0"


def usage_error(code: int, out: str, err: str, option: str) -> str:
    """Click's usage error for a bad option value: exit 2, the option named, no traceback."""
    assert code == 2, (code, out, err)
    assert "Traceback" not in out + err
    assert f"Invalid value for '{option}'" in err, err
    return err


@contextmanager
def within(seconds: int):
    """Fail (instead of hanging) when the block runs longer than `seconds`."""

    def _raise(*_: object) -> None:
        raise TimeoutError(f"still running after {seconds} s")

    old = signal.signal(signal.SIGALRM, _raise)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.fixture()
def scene_file(spec, tmp_path: Path) -> Path:
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(spec))
    return path


# ---------------------------------------------------------------- curbside sim eval / rollout (real process)
SIM_BAD = [
    (["--config", '{"bogus": 1}'], "unknown key 'bogus'"),
    (["--config", "{bad"], "--config is not valid JSON"),
    (["--config", "[1, 2]"], "--config must be a JSON object"),
    (["--config", '{"dt": NaN}'], "config.dt must be a finite number in (0, 1]"),
]


@pytest.mark.parametrize("command", ["eval", "rollout"])
@pytest.mark.parametrize(("args", "needle"), SIM_BAD, ids=["bogus-key", "bad-json", "json-list", "nan-dt"])
def test_sim_bad_config_is_one_line_exit_2(command: str, args: list[str], needle: str, capsys, tmp_path: Path) -> None:
    extra = ["--episodes", "1"] if command == "eval" else ["--out", str(tmp_path / "r.gif")]
    code, out, err = cli(["sim", command, *extra, *args], capsys)
    assert needle in one_error_line(code, out, err) and out == ""
    assert not (tmp_path / "r.gif").exists()


@pytest.mark.parametrize("command", ["eval", "rollout"])
def test_sim_error_is_the_only_stderr_line_of_a_real_process(command: str, tmp_path: Path) -> None:
    extra = ["--episodes", "1"] if command == "eval" else ["--out", str(tmp_path / "r.gif")]
    res = subprocess.run(
        [str(CURBSIDE), "sim", command, *extra, "--config", '{"bogus": 1}'],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=180,
    )
    # pybullet's build-time banner no longer comes before the error line; nothing on stdout.
    assert "unknown key 'bogus'" in one_error_line(res.returncode, res.stdout, res.stderr)
    assert res.stdout == ""


def test_sim_bad_machine_seed_and_scene_path(capsys, tmp_path: Path) -> None:
    err = usage_error(*cli(["sim", "eval", "--episodes", "1", "--machine", "tank"], capsys), "--machine")
    assert "wheelchair" in err
    usage_error(*cli(["sim", "eval", "--episodes", "1", "--seed", "-1"], capsys), "--seed")
    usage_error(*cli(["sim", "rollout", "--seed", "-1", "--out", str(tmp_path / "r.gif")], capsys), "--seed")
    usage_error(*cli(["sim", "eval", "--scene-path", str(tmp_path / "nope.json")], capsys), "--scene-path")
    garbage = tmp_path / "garbage.json"
    garbage.write_text("this is not json")
    line = one_error_line(*cli(["sim", "eval", "--episodes", "1", "--scene-path", str(garbage)], capsys))
    assert "garbage.json is not a scene spec JSON file" in line and "curbside scenes generate" in line
    garbage.write_text('{"version": "curbside.scene/1", "objects": 3}')
    line = one_error_line(
        *cli(["sim", "rollout", "--scene-path", str(garbage), "--out", str(tmp_path / "r.gif")], capsys)
    )
    assert "lacks" in line and "regenerate" in line
    line = one_error_line(*cli(["sim", "rollout", "--out", str(tmp_path)], capsys))
    assert "--out" in line and "is a directory" in line


def test_cli_and_table_choices_match_the_simulator() -> None:
    from curbside.cli.scenes import Preset, RoutePreset, Split
    from curbside.cli.sim import MACHINE_NAMES
    from sim.machines import MACHINES
    from sim.scene.config import PRESETS
    from sim.scene.dataset import SPLITS
    from sim.sensors import ENCODINGS
    from sim.tasks.pointnav import ROUTE_LENGTHS
    from sim.tasks.sensors import LIDAR_TABLE

    assert tuple(MACHINES) == MACHINE_NAMES
    assert [s.value for s in Split] == list(SPLITS) and [p.value for p in Preset] == [*PRESETS, "none"]
    assert [r.value for r in RoutePreset] == list(ROUTE_LENGTHS)
    assert set(LIDAR_TABLE["encoding"].choices) == set(ENCODINGS)


def test_json_on_stdout_is_clean_and_no_pybullet_banner(scene_file: Path, tmp_path: Path) -> None:
    res = subprocess.run(
        [
            str(CURBSIDE),
            "sim",
            "eval",
            "--episodes",
            "1",
            "--scene-path",
            str(scene_file),
            "--json",
            "--config",
            '{"horizon": 5}',
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["episodes"] == 1 and len(res.stdout.strip().splitlines()) == 1
    assert "pybullet build time" not in res.stdout + res.stderr
    # Any sim module imported first (not only the CLI) imports pybullet quietly.
    res = subprocess.run(
        [sys.executable, "-c", "import sim.world, sim.sensors; print('ok')"],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=120,
    )
    assert (res.stdout, res.stderr) == ("ok\n", "")


# ---------------------------------------------------------------- curbside scenes
def test_scenes_generate_bad_numbers(capsys, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # no catalogs/default.duckdb here: its warning must not come before the error
    out = tmp_path / "a.json"
    for value in ("nan", "inf", "-inf", "1e6", "-1"):
        line = one_error_line(*cli(["scenes", "generate", "--object-density", value, "--out", str(out)], capsys))
        assert "object_density must be a finite number in [0, 50]" in line, value
    line = one_error_line(*cli(["scenes", "generate", "--crosswalk-density", "nan", "--out", str(out)], capsys))
    assert "crosswalk_density must be a finite number in [0, 1]" in line
    usage_error(*cli(["scenes", "generate", "--seed", "-5", "--out", str(out)], capsys), "--seed")
    line = one_error_line(*cli(["scenes", "generate", "--out", str(tmp_path)], capsys))
    assert "--out" in line and "is a directory" in line and "scene.json" in line
    assert not out.exists()


def test_scenes_generate_huge_inputs_fail_fast_naming_the_bound(capsys, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    out = str(tmp_path / "a.json")
    with within(20):  # these ran past 120 s before
        line = one_error_line(*cli(["scenes", "generate", "--blocks", "100000", "--out", out], capsys))
        assert "blocks must be 1 to 64" in line
        line = one_error_line(*cli(["scenes", "generate", "--blocks", "S" * 100, "--out", out], capsys))
        assert "blocks must be 1 to 64" in line
        line = one_error_line(
            *cli(["scenes", "generate", "--blocks", "64", "--object-density", "50", "--out", out], capsys)
        )
        assert "blocks x object_density must be <= 640" in line
        line = one_error_line(*cli(["scenes", "generate", "--object-density", "1e6", "--out", out], capsys))
        assert "[0, 50]" in line


def test_scenes_render_and_dataset_bad_numbers(capsys, tmp_path: Path, scene_file: Path) -> None:
    usage_error(
        *cli(["scenes", "render", str(scene_file), "--dpi", "0", "--out", str(tmp_path / "x.png")], capsys), "--dpi"
    )
    usage_error(*cli(["scenes", "dataset", "--count", "-5", "--out", str(tmp_path / "ds")], capsys), "--count")
    usage_error(*cli(["scenes", "dataset", "--count", "0", "--out", str(tmp_path / "ds")], capsys), "--count")
    usage_error(*cli(["scenes", "dataset", "--split", "nope", "--out", str(tmp_path / "ds")], capsys), "--split")
    assert not (tmp_path / "ds").exists()
    bad = json.loads(scene_file.read_text())
    bad["objects"][0]["position"][0] = math.nan
    scene_file.write_text(json.dumps(bad))
    line = one_error_line(*cli(["scenes", "render", str(scene_file), "--out", str(tmp_path / "x.png")], capsys))
    assert "objects[0]" in line and "position must be 3 finite numbers" in line


def test_build_dataset_refuses_a_count_below_one(tmp_path: Path) -> None:
    from sim.scene.dataset import build_dataset

    for count in (-5, 0):
        with pytest.raises(ConfigError, match=r"count must be an integer in \[1, 1000000\]"):
            build_dataset("train", count, tmp_path / "ds")


# ---------------------------------------------------------------- env configs: every key, at construction
def _bad_values(rule) -> list:
    """Values that break `rule` (for numbers: NaN, inf, a string, and just outside each bound)."""
    if rule.kind not in ("int", "float"):
        return []
    vals: list = [math.nan, math.inf, "abc"]
    if rule.lo is not None:
        vals.append(rule.lo - 1 if rule.kind == "int" else (rule.lo if rule.lo_open else rule.lo - 1e-3))
    if rule.hi is not None:
        vals.append(rule.hi + 1)
    if rule.kind == "int":
        vals.append(1.5)
    return vals


def _numeric_cases(table: dict, prefix: tuple = ()) -> list[tuple[tuple, object]]:
    out = []
    for key, rule in table.items():
        if isinstance(rule, dict):
            out += _numeric_cases(rule, prefix + (key,))
        else:
            out += [(prefix + (key,), v) for v in _bad_values(rule)]
    return out


def _nested(path: tuple, value: object) -> dict:
    cfg: dict = {}
    d = cfg
    for k in path[:-1]:
        d = d.setdefault(k, {})
    d[path[-1]] = value
    return cfg


def test_every_config_key_has_a_rule() -> None:
    from sim.scene.config import CONFIG_TABLE as SCENE_TABLE
    from sim.scene.config import DEFAULT_CONFIG as SCENE_DEFAULTS
    from sim.tasks.pointnav import CONFIG_TABLE, DEFAULT_CONFIG
    from sim.tasks.socialnav import CONFIG_TABLE as SOCIAL_TABLE
    from sim.tasks.socialnav import DEFAULT_CONFIG as SOCIAL_DEFAULTS

    assert set(CONFIG_TABLE) == set(DEFAULT_CONFIG)
    assert set(SOCIAL_TABLE) == set(SOCIAL_DEFAULTS)
    from dataclasses import fields

    from sim.tasks.pointnav import Reward

    assert set(CONFIG_TABLE["reward"]) == {f.name for f in fields(Reward)}
    for sub in ("lidar", "render"):
        assert set(CONFIG_TABLE[sub]) == set(DEFAULT_CONFIG[sub]) and set(SOCIAL_TABLE[sub]) == set(
            SOCIAL_DEFAULTS[sub]
        )
    assert set(SCENE_TABLE) == set(SCENE_DEFAULTS)


@pytest.mark.parametrize(
    ("env_id", "table_path"), [(POINTNAV, "sim.tasks.pointnav"), (SOCIALNAV, "sim.tasks.socialnav")]
)
def test_every_bad_number_fails_at_construction_naming_key_and_range(env_id: str, table_path: str) -> None:
    import importlib

    table = importlib.import_module(table_path).CONFIG_TABLE
    cases = _numeric_cases(table)
    assert len(cases) > 100
    for path, value in cases:
        name = "config." + ".".join(path)
        with pytest.raises(ConfigError) as e:
            gym.make(env_id, config=_nested(path, value))
        msg = str(e.value)
        assert msg.startswith(f"{name} must be "), (path, value, msg)
        rule = table
        for k in path:
            rule = rule[k]
        assert rule.describe() in msg  # the valid range is in the message


@pytest.mark.parametrize(
    "cfg",
    [
        {"lidar": {"range": math.nan}},
        {"dt": math.nan},
        {"horizon": "abc"},
        {"num_waypoints": -3},
        {"route_margin": math.nan},
        {"success_completion": 2.0},
        {"route_length": [60.0, 10.0]},
        {"lidar": {"low_range": math.inf}},
        {"render": {"width": 0}},
        {"machine": {"v_max_kmh": math.nan}},
        {"machine": {"base": "wheelchair", "engine_force": [100, math.inf]}},
        {"terminate_off_walkable": "yes"},
        {"cost_kinds": ["object", "lava"]},
        {"scene_path": 3},
    ],
)
def test_pointnav_make_raises_at_construction(cfg: dict) -> None:
    with pytest.raises(ConfigError, match=r"must be|unknown"):
        gym.make(POINTNAV, config=cfg)


@pytest.mark.parametrize(
    "cfg",
    [
        {"agents": {"idle_prob": 2.0}},
        {"agents": {"dynamic_density": math.nan}},
        {"agents": {"idle_time": [8.0, 2.0]}},
        {"agents": {"counts": {"pedestrian": -1}}},
        {"agents": {"mix": {"pedestrian": math.nan}}},
        {"vehicles": {"desired_speed": [math.nan, 12.0]}},
        {"vehicles": {"length": 0}},
        {"traffic": 1},
        {"personal_space": math.inf},
        {"stl_cruise_speed": 0},
        {"render": {"camera": "fisheye"}},
    ],
)
def test_socialnav_make_raises_at_construction(cfg: dict) -> None:
    with pytest.raises(ConfigError, match=r"config\.\w+(\.\w+)? must be|unknown config\.render\.camera"):
        gym.make(SOCIALNAV, config=cfg)


def test_defaults_and_presets_pass() -> None:
    for env_id in (POINTNAV, SOCIALNAV):
        gym.make(env_id).close()
        gym.make(env_id, config={"preset": "metaurban12k"}).close()
        gym.make(env_id, config={"split": "unseen", "machine": {"base": "wheelchair", "engine_force": 150}}).close()


@pytest.mark.parametrize(
    "scene",
    [
        {"object_density": math.nan},
        {"blokcs": 3},
        {"blocks": 100_000},
        {"grid_resolution": 0.0},
        {"block_types": "QQ"},
        {"lane_width": [4.0, 3.0]},
    ],
)
def test_scene_config_errors_surface_at_construction_not_reset(scene: dict) -> None:
    with pytest.raises(ConfigError):
        gym.make(POINTNAV, config={"scene": scene})


def test_scene_json_with_nan_positions_fails_at_construction(spec, tmp_path: Path) -> None:
    for field, value in (("position", [math.nan, 4.8, 0.15]), ("size", [0.2, math.inf, 1.0]), ("yaw", "east")):
        bad = copy.deepcopy(spec)
        bad["objects"][1][field] = value
        path = tmp_path / "bad.json"
        path.write_text(json.dumps(bad))  # json writes NaN / Infinity, and json.loads reads them back
        with pytest.raises(ConfigError, match=rf"objects\[1\] \(id 'o1'\) {field} must be"):
            gym.make(POINTNAV, config={"scene_path": str(path)})
        with pytest.raises(ConfigError, match=rf"objects\[1\] \(id 'o1'\) {field} must be"):
            gym.make(SOCIALNAV, config={"scene_spec": bad})
    bad = copy.deepcopy(spec)
    bad["sidewalks"][0]["polygon"][2] = [math.nan, 1.0]
    with pytest.raises(ConfigError, match=r"sidewalks\[0\] needs a polygon of finite"):
        gym.make(POINTNAV, config={"scene_spec": bad})
    bad = copy.deepcopy(spec)
    bad["walkable"]["resolution"] = 0
    with pytest.raises(ConfigError, match="walkable must hold"):
        gym.make(POINTNAV, config={"scene_spec": bad})


@pytest.mark.parametrize(
    "cfg",
    [
        {"object_density": math.nan},
        {"object_density": math.inf},
        {"curb_height": -0.1},
        {"crosswalk_density": math.nan},
        {"lanes": [1, 9]},
        {"straight_length": [30.0, math.inf]},
        {"grid_resolution": 1e-4},
        {"standard_spacing": 0.01},
        {"placement_tries": 0},
        {"block_tries": 1.5},
        {"buildings": "no"},
        {"preset": "metaurban12k", "fill_gap": 0.0},
        {"blocks": 0},
        {"blocks": 65},
        {"blocks": "S" * 65},
    ],
)
def test_scene_config_rejects_bad_numbers_naming_the_range(cfg: dict) -> None:
    from sim.scene import generate_scene

    with within(20), pytest.raises(ConfigError, match=r"scene config\.\w+ must be"):
        generate_scene(cfg, 0)


# ---------------------------------------------------------------- crash safety: atomic files, resumable datasets
def _state(ds: Path) -> dict[str, tuple[int, int]]:
    return {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in sorted((ds / "scenes").glob("*.json"))}


def test_dataset_resumes_after_a_kill_and_repairs_missing_or_corrupt_files(tmp_path: Path) -> None:
    from sim.scene.dataset import build_dataset

    ds, count = tmp_path / "ds", 10
    args = [
        str(CURBSIDE),
        "scenes",
        "dataset",
        "--split",
        "test",
        "--count",
        str(count),
        "--blocks",
        "1",
        "--preset",
        "none",
        "--out",
        str(ds),
    ]
    proc = subprocess.Popen(args, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        with within(300):
            while len(list((ds / "scenes").glob("*.json"))) < 3 and proc.poll() is None:
                time.sleep(0.02)
        os.kill(proc.pid, signal.SIGKILL)  # mid-way: some scenes written, maybe one half-written temp file
    finally:
        proc.wait()
    before = _state(ds)
    assert 3 <= len(before) < count, "the run finished before it could be killed; raise count"
    for p in (ds / "scenes").glob("*.json"):
        json.loads(p.read_text())  # every scene file present is whole (written atomically)
    assert not (ds / "index.jsonl").exists()

    rows = build_dataset("test", count, ds, base={"blocks": 1})  # the rerun, as `curbside scenes dataset` does it
    after = _state(ds)
    assert len(after) == count and len(rows) == count
    assert all(after[name] == before[name] for name in before)  # complete files were kept, not regenerated
    assert not list((ds / "scenes").glob(".*.tmp"))
    assert [r["seed"] for r in rows] == sorted(r["seed"] for r in rows)

    # Delete one file and corrupt another: a rerun regenerates exactly those two, byte-identical to before.
    names = sorted(after)
    gone, broken = ds / "scenes" / names[1], ds / "scenes" / names[4]
    original = broken.read_bytes()
    gone_bytes = gone.read_bytes()
    gone.unlink()
    broken.write_bytes(original[: len(original) // 2])
    kept = {n: s for n, s in _state(ds).items() if n not in (gone.name, broken.name)}
    rows2 = build_dataset("test", count, ds, base={"blocks": 1})
    final = _state(ds)
    assert {n: final[n] for n in kept} == kept
    assert broken.read_bytes() == original and gone.read_bytes() == gone_bytes
    assert rows2 == rows
    index = [json.loads(x) for x in (ds / "index.jsonl").read_text().splitlines()]
    assert len(index) == count

    # Other settings into the same folder: the files no longer match and are regenerated, not mixed in.
    build_dataset("test", 2, ds, base={"blocks": 1, "object_density": 2.0})
    assert json.loads((ds / "scenes" / names[0]).read_text())["config"]["object_density"] == 2.0
    assert _state(ds)[names[5]] == final[names[5]]


def test_save_is_atomic_and_leaves_no_temp_file(spec, tmp_path: Path) -> None:
    from sim.scene.spec import dumps, save

    path = tmp_path / "s" / "scene.json"
    save(spec, path)
    first_inode = path.stat().st_ino
    save(spec, path)
    assert path.read_text() == dumps(spec)
    assert path.stat().st_ino != first_inode  # replaced by a new file (os.replace), never rewritten in place
    assert [p.name for p in path.parent.iterdir()] == ["scene.json"]
