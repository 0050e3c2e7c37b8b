"""RLlib PPO trains a curbside env with 2 env runners on a local Ray cluster into `curbside train`'s layout, resumes
from its checkpoint, and `curbside train eval` loads the policy (tiny budgets: a few hundred env steps)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from tests.helpers import cli, one_error_line

pytest.importorskip("ray.rllib")
pytestmark = pytest.mark.slow

CFG = {"scene": {"blocks": 1}, "horizon": 100}
TINY = {"n_steps": 64, "batch_size": 64, "n_epochs": 2, "net_arch": [32, 32]}


def _rows(run: Path) -> list[dict[str, str]]:
    with open(run / "logs" / "progress.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_rllib_ppo_trains_checkpoints_resumes_and_evaluates(tmp_path: Path, monkeypatch, capsys) -> None:
    import ray

    from curbside.train import rllib

    monkeypatch.setattr(rllib, "CHECKPOINT_EVERY", 128)
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    # 2 env runners + the learner, one cluster for both runs
    ray.init(address="local", num_cpus=3, include_dashboard=False, log_to_driver=False)
    try:
        _train_resume_eval(tmp_path, capsys)
    finally:
        ray.shutdown()


def _train_resume_eval(tmp_path: Path, capsys) -> None:
    from curbside.train.run import train

    run = tmp_path / "run"
    h = dict(TINY)
    policy = train(
        "ppo",
        "PointNav",
        run,
        steps=256,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams=h,
        executor="ray",
        num_env_runners=2,
        progress=False,
    )
    meta = json.loads((run / "run.json").read_text())
    assert (meta["engine"], meta["num_env_runners"], meta["envs_per_runner"]) == ("rllib", 2, 1)
    assert policy == run / "policy" and (policy / "rllib_checkpoint.json").is_file()
    # 2 runners x 1 env x 64 steps per iteration; SB3's key names in logs/progress.csv, TensorBoard beside it.
    assert [int(r["time/total_timesteps"]) for r in _rows(run)] == [128, 256]
    assert all(r["rollout/ep_len_mean"] or r["train/value_loss"] for r in _rows(run))
    assert list((run / "logs").glob("events.out.tfevents.*"))
    assert sorted(d.name for d in (run / "checkpoints").iterdir()) == ["policy_128_steps", "policy_256_steps"]

    train(
        "ppo",
        "PointNav",
        run,
        steps=384,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams=h,
        executor="ray",
        num_env_runners=2,
        resume=True,
        progress=False,
    )
    assert int(_rows(run)[-1]["time/total_timesteps"]) == 384  # went on from 256, did not start over

    code, out, err = cli(["train", "eval", str(run), "--episodes", "2", "--json", "--config", json.dumps(CFG)], capsys)
    assert code == 0, err
    summary = json.loads(out)
    assert summary["episodes"] == 2 and summary["algo"] == "ppo" and 0.0 <= summary["sr"] <= 1.0


def test_ray_refuses_what_rllib_does_not_train(tmp_path: Path, capsys) -> None:
    line = one_error_line(
        *cli(
            ["train", "run", "--algo", "ppo_lag", "--executor", "ray", "--steps", "10", "--out", str(tmp_path / "r")],
            capsys,
        )
    )
    assert "ppo_lag" in line and "--executor local" in line
    line = one_error_line(*cli(["train", "ppo", "--executor", "process", "--out", str(tmp_path / "r")], capsys))
    assert "--executor local" in line and "ray" in line
