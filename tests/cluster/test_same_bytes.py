"""Scenes, eval metrics and demonstrations are the same bytes whichever executor (local, process, Ray) ran them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.cluster.conftest import tree_bytes
from tests.helpers import cli, one_error_line

EVAL_CFG = {"scene": {"blocks": 1}, "horizon": 300}


@pytest.fixture(scope="module")
def local_dataset(tmp_path_factory: pytest.TempPathFactory, small_catalog: Path) -> Path:
    """Five test-split scenes from the small catalog, generated in this process."""
    from sim.scene.dataset import build_dataset

    out = tmp_path_factory.mktemp("local") / "ds"
    build_dataset("test", 5, out, base={"blocks": 1}, catalog=str(small_catalog), executor="local")
    return out


@pytest.mark.parametrize("executor,workers", [("process", 2), ("ray", 2), ("ray", 1)])
def test_dataset_is_byte_identical_on_every_executor(
    ray_local, local_dataset: Path, small_catalog: Path, tmp_path: Path, executor: str, workers: int
) -> None:
    from sim.scene.dataset import build_dataset

    seen: list[int] = []
    rows = build_dataset(
        "test",
        5,
        tmp_path / "ds",
        base={"blocks": 1},
        catalog=str(small_catalog),
        executor=executor,
        workers=workers,
        progress=seen.append,
    )
    assert [r["seed"] for r in rows] == [1_000_000 + k for k in range(5)]
    assert sum(seen) == 5  # progress reported per scene as workers finish them
    assert tree_bytes(tmp_path / "ds") == tree_bytes(local_dataset)


def test_eval_metrics_are_byte_identical_on_ray(ray_local, tmp_path: Path) -> None:
    from sim.eval import evaluate, write_eval

    local = evaluate("curbside/PointNav-v0", "expert", 4, EVAL_CFG, seed=3)
    sharded = evaluate("curbside/PointNav-v0", "expert", 4, EVAL_CFG, seed=3, executor="ray", workers=2)
    assert json.dumps(sharded, sort_keys=True) == json.dumps(local, sort_keys=True)
    write_eval(local, tmp_path / "local")
    write_eval(sharded, tmp_path / "ray")
    assert tree_bytes(tmp_path / "ray") == tree_bytes(tmp_path / "local")
    rows = (tmp_path / "ray" / "episodes.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == ["3", "4", "5", "6"]  # one row per episode, in seed order


def test_sim_eval_cli_prints_the_same_json_on_ray(ray_local, tmp_path: Path, capsys) -> None:
    args = ["sim", "eval", "--episodes", "3", "--policy", "random", "--config", json.dumps(EVAL_CFG), "--json"]
    code, local, err = cli(args, capsys)
    assert code == 0, err
    code, sharded, err = cli([*args, "--executor", "ray", "--workers", "2", "--out", str(tmp_path / "m")], capsys)
    assert code == 0, err
    assert sharded == local and json.loads(local)["episodes"] == 3
    assert json.loads((tmp_path / "m" / "metrics.json").read_text())["episodes"] == 3


def test_demos_are_byte_identical_on_ray(ray_local, tmp_path: Path) -> None:
    from curbside.train.demos import collect_demos

    kw = {"steps": 250, "noise": 0.5, "random_prob": 0.3, "num_scenes": 2, "env_config": EVAL_CFG, "progress": False}
    a = collect_demos("PointNav", tmp_path / "local", **kw)
    b = collect_demos("PointNav", tmp_path / "ray", executor="ray", workers=2, **kw)
    assert (a["episodes"], a["steps"]) == (b["episodes"], b["steps"]) and a["steps"] >= 250
    local, sharded = tree_bytes(tmp_path / "local"), tree_bytes(tmp_path / "ray")
    meta = "curbside/pointnav-expert-v0/curbside.json"  # holds the dataset's own path
    assert json.loads(local.pop(meta))["success_rate"] == json.loads(sharded.pop(meta))["success_rate"]
    assert sharded == local


def test_address_without_ray_is_one_line_exit_2(capsys) -> None:
    assert "--executor ray" in one_error_line(
        *cli(["sim", "eval", "--episodes", "1", "--address", "10.0.0.1:6379"], capsys)
    )
