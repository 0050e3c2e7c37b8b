"""`curbside scenes stats --vs-paper`: each MetaUrban-12K statistic measured on our scenes, beside the paper's."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from curbside.cli.scenes import app
from sim.scene.paper_stats import PAPER_STATS, scene_figures
from tests.street import street

runner = CliRunner()


def test_figures_of_a_hand_built_scene_are_what_its_spec_says() -> None:
    spec = street()
    figs = scene_figures(spec, np.random.default_rng(0), (10.0, 40.0))
    xmin, ymin, xmax, ymax = spec["bounds"]
    assert figs["objects_per_scene"] == len(spec["objects"])
    assert figs["scene_area_m2"] == pytest.approx((xmax - xmin) * (ymax - ymin))
    assert figs["objects_per_m2"] == pytest.approx(len(spec["objects"]) / figs["scene_area_m2"])
    # The lamps and benches stand in rows a few metres apart: gaps are positive and below their spacing.
    assert 0.0 < figs["nearest_object_m"] < 15.0
    assert 10.0 <= figs["route_length_m"] <= 40.0 and figs["episodes_over_800_steps"] == 0.0


def test_stats_vs_paper_prints_every_statistic_and_writes_the_histograms(tmp_path: Path) -> None:
    ds = tmp_path / "ds"
    assert (
        runner.invoke(app, ["dataset", "--split", "train", "--count", "3", "--blocks", "2", "--out", str(ds)]).exit_code
        == 0
    )
    r = runner.invoke(app, ["stats", str(ds), "--vs-paper", "--route-preset", "short"])
    assert r.exit_code == 0, r.output
    for label in ("objects per scene", "static objects per m²", "PointNav route", "episodes over 800 steps"):
        assert label in r.output
    result = json.loads((ds / "stats_vs_paper.json").read_text())
    assert (
        set(result["table"]) == set(PAPER_STATS)
        and result["scenes"] == 3
        and "meets" in result["table"]["objects_per_m2"]
    )
    row = result["table"]["objects_per_m2"]
    assert row["ratio"] == pytest.approx(row["ours"] / 0.03)
    assert (ds / "stats_vs_paper.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
