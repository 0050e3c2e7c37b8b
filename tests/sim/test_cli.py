"""`curbside sim eval / rollout` on the hand-built scene (typer's runner, real env)."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from curbside.cli.main import app


def test_eval_json_and_rollout_gif(spec, tmp_path):
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(spec))
    runner = CliRunner()
    res = runner.invoke(
        app,
        [
            "sim",
            "eval",
            "--task",
            "PointNav",
            "--policy",
            "expert",
            "--episodes",
            "2",
            "--scene-path",
            str(scene),
            "--json",
        ],
    )
    assert res.exit_code == 0, res.output
    out = json.loads(res.output.strip().splitlines()[-1])
    assert out["episodes"] == 2 and {"sr", "spl", "cost", "route_completion"} <= set(out)
    assert 0.0 <= out["spl"] <= out["sr"] <= 1.0
    bad = runner.invoke(app, ["sim", "eval", "--task", "Fly", "--episodes", "1"])
    assert bad.exit_code != 0 and "PointNav" in bad.output
    gif = tmp_path / "run.gif"
    res = runner.invoke(
        app,
        [
            "sim",
            "rollout",
            "--scene-path",
            str(scene),
            "--out",
            str(gif),
            "--seed",
            "2",
            "--config",
            '{"horizon": 40}',
            "--metrics-out",
            str(tmp_path / "m.json"),
        ],
    )
    assert res.exit_code == 0, res.output
    assert gif.stat().st_size > 1000 and (tmp_path / "run.png").exists()
    assert "route_completion" in json.loads((tmp_path / "m.json").read_text())
