"""The `curbside scenes` commands end to end on small inputs."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from curbside.cli.scenes import app
from sim.scene import load
from tests.helpers import cli, one_error_line

runner = CliRunner()


def test_generate_render_dataset_stats(tmp_path: Path) -> None:
    out = tmp_path / "scene.json"
    r = runner.invoke(app, ["generate", "--blocks", "SX", "--seed", "2", "--templates", "bg", "--out", str(out)])
    assert r.exit_code == 0, r.output
    spec = load(out)
    assert {s["template"] for s in spec["sidewalks"]} <= {"b", "g"}
    png = tmp_path / "scene.png"
    r = runner.invoke(app, ["render", str(out), "--out", str(png), "--dpi", "40"])
    assert r.exit_code == 0, r.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    ds = tmp_path / "ds"
    r = runner.invoke(app, ["dataset", "--split", "unseen", "--count", "3", "--blocks", "2", "--out", str(ds)])
    assert r.exit_code == 0, r.output
    rows = [json.loads(x) for x in (ds / "index.jsonl").read_text().splitlines()]
    assert len(rows) == 3 and all((ds / row["file"]).exists() for row in rows)
    assert all(row["templates"] == "g" and row["split"] == "unseen" for row in rows)
    # The dataset default is the metaurban12k preset: the paper's minimum of 300 objects per scene.
    assert all(row["objects"] >= 300 for row in rows), [row["objects"] for row in rows]
    r = runner.invoke(app, ["stats", str(ds)])
    assert r.exit_code == 0, r.output
    st = json.loads((ds / "stats.json").read_text())
    assert st["scenes"] == 3 and st["objects"]["mean"] > 0 and (ds / "stats.png").exists()


def test_bad_block_code_exits_with_the_valid_codes(tmp_path: Path, capsys) -> None:
    line = one_error_line(*cli(["scenes", "generate", "--blocks", "SQ", "--out", str(tmp_path / "x.json")], capsys))
    assert "valid: S (straight)" in line


def test_train_and_unseen_splits_differ_in_templates_and_categories() -> None:
    from sim.scene.dataset import HELD_OUT_CATEGORIES, split_config

    train, t_off = split_config("train")
    unseen, u_off = split_config("unseen")
    assert train["templates"] == "abcdef" and unseen["templates"] == "g" and t_off != u_off
    assert set(HELD_OUT_CATEGORIES) <= set(train["exclude_categories"]) and not unseen["exclude_categories"]
