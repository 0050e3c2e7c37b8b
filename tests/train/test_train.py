"""Training harness: every baseline trains on tiny budgets, its saved policy reloads and evaluates; demos are
Minari datasets; bad input gets one line and exit code 2 (real SB3, torch, Minari, PyBullet)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from curbside.train.demos import collect_demos, load_demos
from curbside.train.evaluate import evaluate_policy
from curbside.train.policies import ALGOS, load_policy
from curbside.train.run import train
from kernel.config import ConfigError
from tests.helpers import cli, one_error_line

CFG = {"lidar": {"beams": 24, "low_beams": 8}, "route_length": [5.0, 25.0], "scene": {"blocks": 1}}
TINY_PPO = {"n_steps": 64, "batch_size": 64, "n_epochs": 1, "net_arch": [32, 32]}


@pytest.fixture(scope="module")
def demos(tmp_path_factory) -> dict:
    """A small demonstration set on the train split, written as a Minari dataset."""
    return collect_demos(
        "PointNav", tmp_path_factory.mktemp("demos"), steps=300, noise=0.3, env_config=CFG, num_scenes=2, progress=False
    )


def test_demos_collect_writes_where_minari_looks_and_says_how_to_load_it(monkeypatch, tmp_path, capsys) -> None:
    import minari

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    cfg = json.dumps(CFG)
    code, out, err = cli(["demos", "collect", "--steps", "50", "--scenes", "1", "--config", cfg], capsys)
    assert code == 0, err
    assert "minari.load_dataset('curbside/pointnav-expert-v0')" in out and "MINARI_DATASETS_PATH" not in out
    first = minari.load_dataset("curbside/pointnav-expert-v0")
    assert first.total_steps >= 50
    code, out, err = cli(["demos", "collect", "--steps", "80", "--scenes", "1", "--config", cfg], capsys)
    assert code == 0, err  # a second collection replaces the first whole, with no staging folder left
    assert minari.load_dataset("curbside/pointnav-expert-v0").total_steps >= 80
    assert sorted(p.name for p in (tmp_path / "curbside").iterdir()) == ["pointnav-expert-v0"]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".staging")]


def test_demos_are_a_minari_dataset_with_a_success_rate(demos) -> None:
    import minari

    path = Path(demos["path"])
    ds = minari.MinariDataset(path / "data")
    assert ds.total_steps == demos["steps"] >= 300 and ds.total_episodes == demos["episodes"]
    assert 0.0 <= demos["success_rate"] <= 1.0
    assert ds.spec.env_spec.id == "curbside/PointNav-v0"  # offline libraries can recover the env
    tr, meta = load_demos(path)
    assert len(tr) == demos["steps"] and tr.obs.shape == (len(tr), 24 + 8 + 6 + 20 + 3)
    ends = tr.terminals | tr.timeouts
    assert ends.sum() == demos["episodes"] and ends[-1]  # every episode ends exactly once
    inside = ~ends[:-1]  # within an episode, a step's next observation is the following step's observation
    assert np.array_equal(tr.next_obs[:-1][inside], tr.obs[1:][inside])
    assert meta["success_rate"] == demos["success_rate"]


@pytest.mark.parametrize("algo", ALGOS)
def test_each_algorithm_trains_saves_reloads_and_evaluates(algo, demos, tmp_path) -> None:
    steps = 128 if algo in ("ppo", "ppo_lag", "ppo_et", "gail") else 40
    out = tmp_path / algo
    hparams = TINY_PPO if algo in ("ppo", "ppo_lag", "ppo_et", "gail") else {"net_arch": [32, 32]}
    path = train(
        algo,
        "PointNav",
        out,
        steps=steps,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        demos=Path(demos["path"]),
        hparams=hparams,
        progress=False,
        subprocess=False,
    )
    assert path.is_file() and (out / "run.json").is_file()
    act, run = load_policy(out)
    assert run["algo"] == algo
    obs = np.zeros(24 + 8 + 6 + 20 + 3, dtype=np.float32)
    a = np.asarray(act(obs))
    assert a.shape == (2,) and np.isfinite(a).all()
    summary = evaluate_policy(act, "PointNav", CFG, split="test", episodes=1, num_scenes=1, progress=False)
    assert summary["episodes"] == 1 and 0.0 <= summary["sr"] <= 1.0 and "spl" in summary
    if algo in ("iql", "td3bc"):  # deterministic actors: asking for draws is refused in one line
        with pytest.raises(ConfigError, match="deterministically only"):
            load_policy(out, deterministic=False)
    else:  # draws from the policy's distribution: they vary around the mean, and torch's seed repeats them
        draw, _ = load_policy(out, deterministic=False)
        torch.manual_seed(0)
        first = [np.asarray(draw(obs)) for _ in range(3)]
        torch.manual_seed(0)
        again = [np.asarray(draw(obs)) for _ in range(3)]
        assert all(np.array_equal(x, y) for x, y in zip(first, again))
        assert not all(np.allclose(x, a) for x in first)
    if algo == "gail":  # the discriminator learned after each rollout and logged beside the generator
        header = (out / "logs" / "progress.csv").read_text().splitlines()[0].split(",")
        assert {"gail/disc_loss", "gail/disc_acc_expert"} <= set(header) and (out / "discriminator.pt").is_file()


def test_gail_generator_trains_on_the_batched_backend(demos, tmp_path) -> None:
    from stable_baselines3 import PPO

    out = tmp_path / "gail"
    train(
        "gail",
        "PointNav",
        out,
        steps=128,
        backend="batched",
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        demos=Path(demos["path"]),
        hparams=TINY_PPO,
        progress=False,
    )
    assert json.loads((out / "run.json").read_text())["backend"] == "batched"
    assert PPO.load(out / "policy.zip", device="cpu").num_timesteps >= 128
    rows = (out / "logs" / "progress.csv").read_text().splitlines()
    header = rows[0].split(",")
    assert len(rows) >= 2 and "gail/disc_acc_expert" in header  # the discriminator learned on the batched rollouts


def test_socialnav_ppo_lag_trains_on_the_batched_backend(tmp_path) -> None:
    """SocialNav's online learners step sim.batched's BatchedSocialNav; PPO-Lag's cost signal includes agents."""
    from stable_baselines3 import PPO

    out = tmp_path / "social"
    train(
        "ppo_lag",
        "SocialNav",
        out,
        steps=128,
        backend="batched",
        env_config={**CFG, "agents": {"dynamic_density": 20.0}},
        n_envs=2,
        num_scenes=2,
        hparams=TINY_PPO,
        progress=False,
    )
    run = json.loads((out / "run.json").read_text())
    assert (run["backend"], run["task"]) == ("batched", "SocialNav")
    assert PPO.load(out / "policy.zip", device="cpu").num_timesteps >= 128


def test_a_run_env_config_overrides_its_backend_scene_reuse(tmp_path, monkeypatch) -> None:
    """The protocol's training envs keep a scene for its backend's `scene_steps`; a run that sets its own (ablation
    (b)) trains with that, and records it."""
    import dataclasses

    import curbside.train.envs as envs
    from curbside.train import protocols

    reuse = {"batched": {"scene_steps": 20_000, "route_pool": 16}}
    monkeypatch.setitem(
        protocols.PROTOCOLS,
        "curbside",
        dataclasses.replace(protocols.PROTOCOLS["curbside"], training_config=reuse),
    )
    seen: list[dict] = []
    real = envs.make_training_vec
    monkeypatch.setattr(
        envs,
        "make_training_vec",
        lambda task, config, *a, **kw: (seen.append(dict(config)), real(task, config, *a, **kw))[1],
    )
    out = tmp_path / "ppo"
    train(
        "ppo",
        "PointNav",
        out,
        steps=128,
        backend="batched",
        env_config={**CFG, "scene_steps": 7},
        n_envs=2,
        num_scenes=2,
        hparams=TINY_PPO,
        progress=False,
    )
    assert seen[0]["scene_steps"] == 7 and seen[0]["route_pool"] == 16
    recorded = json.loads((out / "run.json").read_text())["env_config"]
    assert recorded["scene_steps"] == 7 and "route_pool" not in recorded


def test_a_killed_gail_run_resumes_from_its_last_round(demos, tmp_path, monkeypatch) -> None:
    from stable_baselines3 import PPO

    import curbside.train.imitate as imitate

    out = tmp_path / "gail"
    kw = dict(env_config=CFG, n_envs=2, num_scenes=2, demos=Path(demos["path"]), hparams=TINY_PPO, progress=False)
    real = imitate.Discriminator.train
    rounds: list[int] = []

    def killed_in_third_round(self, *a, **k):
        rounds.append(1)
        if len(rounds) == 3:
            raise KeyboardInterrupt  # killed before the third round's checkpoint
        return real(self, *a, **k)

    monkeypatch.setattr(imitate.Discriminator, "train", killed_in_third_round)
    with pytest.raises(KeyboardInterrupt):
        train("gail", "PointNav", out, steps=512, subprocess=False, **kw)
    saved = PPO.load(out / "checkpoints" / imitate.GAIL_GENERATOR, device="cpu")
    assert saved.num_timesteps == 256 and not (out / "policy.zip").exists()  # two rounds of 2 envs x 64 steps
    disc = torch.load(out / "checkpoints" / imitate.GAIL_DISCRIMINATOR, weights_only=True)
    assert set(disc) == {"net", "opt", "generator"}

    rounds.clear()
    train("gail", "PointNav", out, steps=512, resume=True, subprocess=False, **kw)
    assert len(rounds) == 2  # the two rounds left, not four
    assert PPO.load(out / "policy.zip", device="cpu").num_timesteps == 512


def test_ppo_lag_raises_lambda_when_cost_exceeds_the_limit(tmp_path) -> None:
    # cost_limit -1 can never be met: lambda must grow from its start after every rollout with an episode end.
    h = {**TINY_PPO, "cost_limit": -1.0, "lag_lr": 0.5, "lag_init": 0.0}
    train(
        "ppo_lag",
        "PointNav",
        tmp_path,
        steps=256,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams=h,
        progress=False,
        subprocess=False,
    )
    rows = (tmp_path / "logs" / "progress.csv").read_text().splitlines()
    header = rows[0].split(",")
    lam = [
        float(r.split(",")[header.index("lagrange/lambda")])
        for r in rows[1:]
        if r.split(",")[header.index("lagrange/lambda")]
    ]
    assert lam[-1] > 0.0


@pytest.mark.parametrize("limit", [0.0, 1.0, 3.0])
def test_ppo_et_ends_the_episode_once_its_cost_exceeds_the_limit(spec, limit) -> None:
    # MetaUrban's PPO-ET rule: the episode stops when the cost exceeds the limit (not at the first cost step).
    import gymnasium as gym

    from curbside.train.online import early_termination_config

    base = {"scene_spec": spec, "terminate_off_walkable": False, "out_of_route_distance": 50.0, "collision_steps": 0}
    env = gym.make("curbside/PointNav-v0", config=early_termination_config(base, limit))
    env.reset(seed=0, options={"start": [10.0, 7.0], "goal": [25.0, 7.0]})
    costs = []
    for _ in range(300):
        _, r, term, trunc, info = env.step([0.0, 1.0])  # straight into the trash bin on the sidewalk
        costs.append(info["cost"])
        if term or trunc:
            break
    assert term and info["cost_exceeded"] and info["end_reason"] == "cost_exceeded"
    assert sum(costs) == info["episode_cost"] == int(limit) + 1  # the first step past the limit ends it
    assert not any(np.cumsum(costs)[:-1] > limit)


def test_batched_env_ends_episodes_at_the_same_cost_as_the_pybullet_env(spec) -> None:
    from curbside.train.online import early_termination_config
    from sim.batched import BatchedPointNav

    base = {"scene_spec": spec, "terminate_off_walkable": False, "out_of_route_distance": 50.0, "collision_steps": 0}
    env = BatchedPointNav(1, config=early_termination_config(base, 2.0))
    env.reset(seed=0, options={"start": [10.0, 7.0], "goal": [25.0, 7.0]})
    total = 0.0
    for _ in range(300):
        _, _, term, trunc, info = env.step(np.array([[0.0, 1.0]]))
        total += info["cost"][0]
        if term[0] or trunc[0]:
            break
    assert term[0] and info["final_info"]["cost_exceeded"][0] and total == 3.0


def test_resume_continues_from_the_latest_checkpoint(tmp_path) -> None:
    train(
        "ppo",
        "PointNav",
        tmp_path,
        steps=128,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams=TINY_PPO,
        progress=False,
        subprocess=False,
    )
    ckpt = tmp_path / "checkpoints"
    ckpt.mkdir(exist_ok=True)
    (tmp_path / "policy.zip").rename(ckpt / "policy_128_steps.zip")
    train(
        "ppo",
        "PointNav",
        tmp_path,
        steps=256,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams=TINY_PPO,
        progress=False,
        subprocess=False,
        resume=True,
    )
    from stable_baselines3 import PPO

    assert PPO.load(tmp_path / "policy.zip").num_timesteps == 256


def test_checkpoints_are_whole_and_a_resume_skips_a_truncated_one(tmp_path, monkeypatch) -> None:
    from stable_baselines3 import PPO

    from curbside.train import online

    monkeypatch.setattr(online, "CHECKPOINT_EVERY", 64)
    kwargs = dict(env_config=CFG, n_envs=2, num_scenes=2, hparams=TINY_PPO, progress=False, subprocess=False)
    train("ppo", "PointNav", tmp_path, steps=128, **kwargs)
    ckpt = tmp_path / "checkpoints"
    assert sorted(f.name for f in ckpt.iterdir()) == ["policy_128_steps.zip", "policy_64_steps.zip"]
    assert PPO.load(ckpt / "policy_128_steps.zip").num_timesteps == 128
    # A kill while a trainer wrote in place leaves the newest checkpoint cut short: resume from the one before.
    whole = (ckpt / "policy_128_steps.zip").read_bytes()
    (ckpt / "policy_192_steps.zip").write_bytes(whole[: len(whole) // 2])
    with pytest.warns(UserWarning, match="policy_192_steps.zip is not a whole SB3 zip"):
        assert online.latest_checkpoint(ckpt) == ckpt / "policy_128_steps.zip"
    with pytest.warns(UserWarning, match="policy_192_steps.zip is not a whole SB3 zip"):
        train("ppo", "PointNav", tmp_path, steps=256, resume=True, **kwargs)
    assert PPO.load(tmp_path / "policy.zip").num_timesteps == 256
    # The progress log goes on from the checkpoint: the first run's rows, then the resumed run's.
    with open(tmp_path / "logs" / "progress.csv", newline="") as f:
        logged = [int(r["time/total_timesteps"]) for r in csv.DictReader(f)]
    assert logged == [128, 256]
    assert (ckpt / "policy_256_steps.zip").is_file() and not list(ckpt.glob("*.tmp*"))


def test_unknown_algorithm_is_one_line_exit_2(tmp_path, capsys) -> None:
    line = one_error_line(*cli(["train", "run", "--algo", "dqn", "--out", str(tmp_path)], capsys))
    assert "unknown algorithm 'dqn'" in line and "ppo, ppo_lag" in line


def test_missing_demo_file_is_one_line_exit_2(tmp_path, capsys) -> None:
    line = one_error_line(
        *cli(
            ["train", "run", "--algo", "bc", "--demos", str(tmp_path / "nope"), "--out", str(tmp_path / "run")], capsys
        )
    )
    assert "no demonstration dataset" in line and "curbside demos collect" in line
    line = one_error_line(*cli(["train", "run", "--algo", "iql", "--out", str(tmp_path / "run")], capsys))
    assert "--demos" in line


def test_a_split_with_no_scenes_is_one_line_exit_2(tmp_path, capsys) -> None:
    from sim.scene.dataset import build_dataset

    build_dataset("test", 1, tmp_path / "scenes", base={"blocks": 1})
    cfg = json.dumps({"scene_dir": str(tmp_path / "scenes"), "num_scenes": None})
    line = one_error_line(*cli(["train", "run", "--config", cfg, "--out", str(tmp_path / "run")], capsys))
    assert "split 'train' has no scenes" in line and "curbside scenes dataset --split train" in line


def test_eval_of_a_folder_that_is_not_a_run_is_one_line_exit_2(tmp_path, capsys) -> None:
    line = one_error_line(*cli(["train", "eval", str(tmp_path)], capsys))
    assert "not a training run" in line and "curbside train run" in line


def test_eval_with_unknown_actions_or_sampled_actions_of_a_deterministic_actor_is_one_line_exit_2(
    demos, tmp_path, capsys
) -> None:
    train("td3bc", "PointNav", tmp_path, steps=5, env_config=CFG, demos=Path(demos["path"]), progress=False)
    line = one_error_line(*cli(["train", "eval", str(tmp_path), "--actions", "greedy"], capsys))
    assert "unknown --actions 'greedy'; valid: mean, sampled" in line
    line = one_error_line(*cli(["train", "eval", str(tmp_path), "--actions", "sampled"], capsys))
    assert "acts deterministically only" in line
    # Without --actions the run's protocol decides, and an actor that cannot sample acts with its one action.
    code, out, _ = cli(["train", "eval", str(tmp_path), "--episodes", "1", "--json"], capsys)
    assert code == 0 and json.loads(out)["actions"] == "mean"


def test_bad_config_json_is_one_line_exit_2(tmp_path, capsys) -> None:
    line = one_error_line(*cli(["train", "run", "--config", "{bad", "--out", str(tmp_path)], capsys))
    assert "--config is not valid JSON" in line
    line = one_error_line(*cli(["demos", "collect", "--config", '{"bogus": 1}', "--out", str(tmp_path)], capsys))
    assert "unknown key 'bogus'" in line


def test_offline_trains_exactly_the_steps_asked(demos, tmp_path) -> None:
    train("td3bc", "PointNav", tmp_path, steps=30, env_config=CFG, demos=Path(demos["path"]), progress=False)
    log = json.loads((tmp_path / "train_log.json").read_text())
    assert log[-1]["gradient_steps"] == 30


def test_ppo_lag_keeps_lambda_across_resume(tmp_path) -> None:
    h = {**TINY_PPO, "cost_limit": -1.0, "lag_lr": 0.5, "lag_init": 0.0}
    train(
        "ppo_lag",
        "PointNav",
        tmp_path,
        steps=256,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams=h,
        progress=False,
        subprocess=False,
    )
    lam = json.loads((tmp_path / "lagrange.json").read_text())["lambda"]
    ckpt = tmp_path / "checkpoints"
    ckpt.mkdir(exist_ok=True)
    (tmp_path / "policy.zip").rename(ckpt / "policy_256_steps.zip")
    # The resumed part freezes the multiplier (lag_lr 0; a resume goes on under the hyper-parameters its run.json
    # records, so they are set there too): lambda must come back as saved, not as lag_init.
    meta = json.loads((tmp_path / "run.json").read_text())
    meta["hparams"]["lag_lr"] = 0.0
    (tmp_path / "run.json").write_text(json.dumps(meta))
    train(
        "ppo_lag",
        "PointNav",
        tmp_path,
        steps=384,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams={**h, "lag_lr": 0.0},
        progress=False,
        subprocess=False,
        resume=True,
    )
    assert lam > 0.0 and json.loads((tmp_path / "lagrange.json").read_text())["lambda"] == lam


def test_workers_shard_the_scenes_of_a_dataset_folder(tmp_path) -> None:
    from curbside.train.envs import env_fns
    from sim.scene.dataset import build_dataset

    build_dataset("train", 4, tmp_path, base={"blocks": 1})
    fns = env_fns("PointNav", {"scene_dir": str(tmp_path), "route_length": [5.0, 20.0]}, 2, 4)
    shards = []
    for fn in fns:
        env = fn()
        shards.append({str(f) for f in env.unwrapped.scenes.files})
        env.close()
    assert len(shards[0]) == len(shards[1]) == 2 and not shards[0] & shards[1]


def test_subprocess_workers_build_their_envs() -> None:
    from curbside.train.envs import make_vec_env

    vec = make_vec_env("PointNav", CFG, 2, 2, subprocess=True)
    try:
        obs = vec.reset()
        obs, rewards, dones, infos = vec.step(np.zeros((2, 2), dtype=np.float32))
        assert obs.shape == (2, 24 + 8 + 6 + 20 + 3) and rewards.shape == (2,)
    finally:
        vec.close()


def test_a_run_is_never_overwritten_and_resume_needs_the_same_run(demos, tmp_path, capsys) -> None:
    out = tmp_path / "bc"
    train(
        "bc",
        "PointNav",
        out,
        steps=5,
        env_config=CFG,
        demos=Path(demos["path"]),
        progress=False,
        hparams={"net_arch": [16]},
    )
    before = (out / "policy.zip").read_bytes()
    base = ["train", "run", "--steps", "64", "--envs", "2", "--scenes", "2", "--config", json.dumps(CFG)]
    line = one_error_line(*cli([*base, "--algo", "ppo", "--out", str(out)], capsys))
    assert "already holds a bc run on PointNav" in line and "--resume" in line
    line = one_error_line(*cli([*base, "--algo", "ppo", "--resume", "--out", str(out)], capsys))
    assert "it holds a bc run on PointNav, not ppo on PointNav" in line
    line = one_error_line(*cli([*base, "--algo", "ppo", "--task", "SocialNav", "--resume", "--out", str(out)], capsys))
    assert "not ppo on SocialNav" in line
    line = one_error_line(*cli([*base, "--algo", "ppo", "--resume", "--out", str(tmp_path / "empty")], capsys))
    assert "holds no run to continue" in line
    assert (out / "policy.zip").read_bytes() == before


def test_hparams_override_the_protocols_and_the_run_records_them(tmp_path, capsys) -> None:
    out = tmp_path / "run"
    tiny = {"n_steps": 32, "batch_size": 32, "n_epochs": 1, "net_arch": [16, 16], "gamma": 0.95}
    argv = ["train", "run", "--steps", "64", "--envs", "2", "--scenes", "2", "--config", json.dumps(CFG)]
    code, _, err = cli([*argv, "--hparams", json.dumps(tiny), "--eval-every", "0", "--out", str(out)], capsys)
    assert code == 0, err
    recorded = json.loads((out / "run.json").read_text())["hparams"]
    assert {k: recorded[k] for k in tiny} == tiny and recorded["learning_rate"] == 3e-4  # the rest: the protocol's
    # A resume goes on under the values the run started with: other ones are refused in one line, naming them.
    again = [*argv, "--steps", "128", "--eval-every", "0", "--resume", "--out", str(out)]
    line = one_error_line(*cli([*again, "--hparams", json.dumps({**tiny, "gamma": 0.9})], capsys))
    assert "it trained with hparams.gamma = 0.95, this command gives 0.9" in line and "--hparams" in line
    code, _, err = cli([*again, "--hparams", json.dumps(tiny)], capsys)
    assert code == 0, err


def test_a_policy_save_that_fails_leaves_the_previous_policy(tmp_path) -> None:
    """save_policy writes beside the old file and swaps: a save that fails (here its temporary path is a folder, so
    SB3 writes elsewhere and the swap fails) raises and leaves the previous policy as it was."""
    from stable_baselines3 import PPO

    from curbside.train.policies import save_policy

    model = PPO("MlpPolicy", "Pendulum-v1", n_steps=64, batch_size=64, device="cpu", seed=0)
    path = save_policy(model, tmp_path / "policy.zip")
    before = path.read_bytes()
    (tmp_path / "policy.tmp.zip").mkdir()
    with pytest.warns(UserWarning, match="is a folder"), pytest.raises(NotADirectoryError):
        save_policy(model, path)
    assert path.read_bytes() == before
    assert PPO.load(path, device="cpu").n_steps == 64
