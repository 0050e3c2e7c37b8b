"""Protocols (curbside, paper, paper_realistic), the batched training backend, fine-tuning from a run, the finetune split and seeds:
real SB3 and torch learners, real envs."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from curbside.train.protocols import PROTOCOLS, protocol
from curbside.train.run import resolve_run, train
from kernel.config import ConfigError
from tests.helpers import cli, one_error_line

CFG = {"lidar": {"beams": 24, "low_beams": 8}, "route_length": [5.0, 25.0], "scene": {"blocks": 1}}
TINY = {"n_steps": 64, "batch_size": 64, "n_epochs": 1, "net_arch": [32, 32]}


@pytest.mark.parametrize("name", ["paper", "paper_realistic"])
def test_paper_protocols_keep_the_papers_splits_and_ppo_table(name) -> None:
    # MetaUrban, ICLR 2025, Sec. 4 (MetaUrban-12K's splits) and the appendix's PPO / PPO-Lag / PPO-ET table.
    p = protocol(name)
    for algo in ("ppo", "ppo_lag", "ppo_et"):
        h = p.algo_hparams(algo)
        assert (
            h["learning_rate"],
            h["train_batch"],
            h["batch_size"],
            h["gamma"],
            h["gae_lambda"],
            h["clip_range"],
            h["vf_coef"],
            h["ent_coef"],
            h["cost_limit"],
        ) == (5e-5, 25_600, 256, 0.99, 0.95, 0.2, 1.0, 0.0, 1.0)
    assert [p.scenes(s) for s in ("train", "test", "unseen", "finetune")] == [12_800, 1_000, 100, 1_000]
    assert p.eval_episodes >= 200


def test_paper_realistic_is_the_protocol_of_every_shipped_experiment() -> None:
    from curbside.experiments.spec import HERE, names
    from kernel.config import load_yaml

    realistic = protocol("paper_realistic")
    assert realistic.name == "paper_realistic" and "80 kg" in realistic.description
    assert list(PROTOCOLS).index("paper_realistic") == list(PROTOCOLS).index("paper") + 1
    # Each shipped yaml names its protocol itself, and names one that exists.
    declared = {n: load_yaml((HERE / f"{n}.yaml").read_text(), n).get("protocol") for n in names()}
    assert declared and all(p in PROTOCOLS for p in declared.values()), declared
    assert declared["table1_paper"] == "paper_realistic"


def test_paper_realistic_protocol_selects_the_tables_hyper_parameters(tmp_path) -> None:
    # MetaUrban, ICLR 2025, appendix tables: the values a paper_realistic run trains with, down to the SB3 objects.
    ppo = resolve_run("ppo", "PointNav", protocol="paper_realistic")
    h = ppo["hparams"]
    assert (
        h["learning_rate"],
        h["gamma"],
        h["gae_lambda"],
        h["clip_range"],
        h["batch_size"],
        h["vf_coef"],
        h["ent_coef"],
        h["cost_limit"],
    ) == (5e-5, 0.99, 0.95, 0.2, 256, 1.0, 0.0, 1.0)
    assert h["n_steps"] * ppo["n_envs"] == 25_600  # the paper's train batch
    assert h["n_epochs"] == 30  # not in the paper: RLlib's default num_sgd_iter, as its table's settings are RLlib's
    assert ppo["env_config"]["preset"] == "metaurban12k" and ppo["num_scenes"] == 12_800
    # MetaUrban's eval_ppo.py calls SB3's predict with its default: the policy's draws, not its mean.
    realistic = protocol("paper_realistic")
    assert realistic.eval_actions == "sampled" and "eval_ppo.py" in realistic.sources["eval_actions"]
    bc = resolve_run("bc", "PointNav", protocol="paper_realistic")["hparams"]
    assert (bc["learning_rate"], bc["batch_size"]) == (1e-4, 64)
    from curbside.experiments.spec import budget_of, load_experiment

    assert budget_of(load_experiment("table1_paper"), "paper")["bc_steps"] == 40 * 30_000 // 64  # 40 epochs
    iql = resolve_run("iql", "PointNav", protocol="paper_realistic")["hparams"]
    assert (iql["learning_rate"], iql["tau"], iql["beta"], iql["expectile"]) == (1e-4, 5e-3, 3.0, 0.7)
    td3 = resolve_run("td3bc", "PointNav", protocol="paper_realistic")["hparams"]
    assert (td3["learning_rate"], td3["alpha"], td3["actor_delay"]) == (1e-4, 2.5, 2)
    gail = resolve_run("gail", "PointNav", protocol="paper_realistic")["hparams"]
    assert (gail["learning_rate"], gail["disc_lr"], gail["demo_batch_size"], gail["n_epochs"]) == (1e-4, 3e-3, 64, 5)
    assert gail["n_steps"] * 8 == 12_800  # the sample batch, over the PyBullet backend's 8 envs

    from stable_baselines3 import PPO

    from curbside.train.envs import make_training_vec
    from curbside.train.online import ppo_kwargs

    vec = make_training_vec("PointNav", CFG, 2, 2, subprocess=False)
    try:
        model = PPO(
            "MlpPolicy",
            vec,
            device="cpu",
            **ppo_kwargs(resolve_run("ppo", "PointNav", protocol="paper_realistic", n_envs=2)["hparams"]),
        )
    finally:
        vec.close()
    assert (model.learning_rate, model.vf_coef, model.n_steps * 2, model.batch_size) == (5e-5, 1.0, 25_600, 256)
    from curbside.train.offline import IQL, OfflineHparams

    learner = IQL(8, 2, OfflineHparams.of(iql))
    assert (learner.h.beta, learner.h.expectile, learner.h.tau, learner.h.batch_size) == (3.0, 0.7, 5e-3, 256)
    assert {g["lr"] for opt in (learner.actor_opt, learner.v_opt, learner.q.opt) for g in opt.param_groups} == {1e-4}


def test_protocol_envs_follow_the_backend_and_configs_merge_key_by_key() -> None:
    batched = resolve_run("ppo", "PointNav", protocol="paper_realistic", backend="batched")
    pybullet = resolve_run("ppo", "PointNav", protocol="paper_realistic", backend="pybullet")
    assert (batched["n_envs"], batched["hparams"]["n_steps"]) == (64, 400)
    assert (pybullet["n_envs"], pybullet["hparams"]["n_steps"]) == (8, 3_200)
    lidar = resolve_run("ppo", "PointNav", protocol="paper_realistic", env_config={"lidar": {"beams": 120}})[
        "env_config"
    ]["lidar"]
    assert lidar == {"resolution": 0.1, "beams": 120}  # the protocol's grid resolution survives a partial override
    # Scene reuse is the training envs' alone: each backend's own, none under curbside, none in the run's env_config.
    realistic = protocol("paper_realistic")
    assert realistic.backend_config("batched")["scene_steps"] > realistic.backend_config("pybullet")["scene_steps"] > 0
    assert protocol("curbside").backend_config("pybullet") == {}
    assert "scene_steps" not in pybullet["env_config"]


def test_curbside_protocol_keeps_the_learnable_defaults() -> None:
    r = resolve_run("ppo", "PointNav")
    assert r["env_config"] == {} and r["n_envs"] == 8 and r["num_scenes"] == 64
    assert r["hparams"]["learning_rate"] == 3e-4 and r["hparams"]["n_steps"] == 512
    assert protocol("curbside").eval_actions == "mean"
    assert set(PROTOCOLS) == {"curbside", "paper", "paper_realistic"}


def _curve(run: Path) -> list[dict[str, float]]:
    with open(run / "eval_curve.csv", newline="") as f:
        return [{k: float(v) for k, v in row.items() if v != ""} for row in csv.DictReader(f)]


def test_batched_backend_trains_ppo_and_the_finetune_split_trains(tmp_path) -> None:
    src = tmp_path / "src"
    train(
        "ppo",
        "PointNav",
        src,
        steps=256,
        backend="batched",
        env_config=CFG,
        n_envs=4,
        num_scenes=2,
        hparams=TINY,
        progress=False,
    )
    run = json.loads((src / "run.json").read_text())
    assert (run["backend"], run["split"], run["protocol"]) == ("batched", "train", "curbside")
    from stable_baselines3 import PPO

    assert PPO.load(src / "policy.zip").num_timesteps >= 256
    fine = tmp_path / "fine"
    train(
        "ppo",
        "PointNav",
        fine,
        steps=128,
        split="finetune",
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams=TINY,
        progress=False,
        subprocess=False,
    )
    assert json.loads((fine / "run.json").read_text())["split"] == "finetune"
    assert PPO.load(fine / "policy.zip").num_timesteps >= 128


def test_init_from_reproduces_the_source_policys_evaluation_before_training(tmp_path) -> None:
    from curbside.train.evaluate import evaluate_policy
    from curbside.train.policies import load_policy

    src = tmp_path / "src"
    train(
        "ppo",
        "PointNav",
        src,
        steps=128,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams=TINY,
        progress=False,
        subprocess=False,
    )
    act, _ = load_policy(src)
    source_eval = evaluate_policy(act, "PointNav", CFG, split="test", episodes=3, progress=False)
    fine = tmp_path / "fine"
    train(
        "ppo",
        "PointNav",
        fine,
        steps=128,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams=TINY,
        progress=False,
        subprocess=False,
        init_from=src,
        eval_every=10_000,
        eval_episodes=3,
        split="finetune",
    )
    first = _curve(fine)[0]
    assert first["steps"] == 0
    for k in ("sr", "spl", "cost", "route_completion", "path_length"):
        assert first[k] == pytest.approx(source_eval[k])
    # and it is a real start: a run from scratch evaluates otherwise
    scratch = tmp_path / "scratch"
    train(
        "ppo",
        "PointNav",
        scratch,
        steps=128,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams=TINY,
        seed=5,
        progress=False,
        subprocess=False,
        eval_every=10_000,
        eval_episodes=3,
    )
    assert _curve(scratch)[0]["path_length"] != pytest.approx(source_eval["path_length"])


def test_seeds_are_aggregated_as_mean_and_std(tmp_path) -> None:
    from curbside.train.seeds import aggregate_seeds

    for s in (0, 1):  # what `train run --seeds 0,1` runs, one folder a seed
        train(
            "ppo",
            "PointNav",
            tmp_path / f"seed_{s}",
            steps=64,
            env_config=CFG,
            n_envs=2,
            num_scenes=2,
            hparams=TINY,
            seed=s,
            eval_every=64,
            eval_episodes=2,
            progress=False,
            subprocess=False,
        )
    summary = aggregate_seeds(tmp_path, [0, 1])
    assert json.loads((tmp_path / "seeds.json").read_text()) == summary
    assert summary["evaluated"] == [0, 1] and summary["sr"]["n"] == 2
    finals = [summary["runs"][s]["path_length"] for s in ("0", "1")]
    assert finals[0] != finals[1]  # two seeds, two policies
    assert summary["path_length"]["mean"] == pytest.approx(np.mean(finals))
    assert summary["path_length"]["std"] == pytest.approx(np.std(finals))


@pytest.mark.parametrize(
    "args, expected",
    [
        (["--protocol", "papr"], "unknown protocol 'papr'; valid: curbside, paper, paper_realistic"),
        (
            ["--protocol", "paper", "--config", '{"machine": "coco"}'],
            "unknown machine 'coco'; valid machines: delivery_bot, delivery_bot_mod1",
        ),
        (["--backend", "gpu"], "unknown backend 'gpu'; valid: pybullet, batched"),
        (["--backend", "batched", "--task", "Social"], "unknown task 'Social'; valid: PointNav, SocialNav"),
        (
            ["--backend", "batched", "--algo", "bc", "--demos", "."],
            "the batched backend trains ppo, ppo_lag, ppo_et, gail",
        ),
        (["--split", "test"], "--split test is held out for evaluation"),
        (["--split", "validation"], "unknown split 'validation'"),
        (["--seeds", "0,x"], "--seeds must be comma-separated integers"),
        (["--config", '{"split": "test"}'], "config.split 'test' differs from --split 'train'"),
        (["--hparams", '{"epochs": 3}'], "unknown ppo hyper-parameter(s) ['epochs']; valid: batch_size"),
        (["--hparams", "[30]"], "--hparams must be a JSON object"),
    ],
)
def test_bad_protocol_backend_split_or_seeds_is_one_line_exit_2(tmp_path, capsys, args, expected) -> None:
    line = one_error_line(*cli(["train", "run", "--out", str(tmp_path / "run"), *args], capsys))
    assert expected in line


def test_init_from_another_task_or_observation_space_is_one_line_exit_2(tmp_path, capsys) -> None:
    src = tmp_path / "src"
    train(
        "ppo",
        "PointNav",
        src,
        steps=64,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams=TINY,
        progress=False,
        subprocess=False,
    )
    base = ["train", "run", "--out", str(tmp_path / "run"), "--init-from", str(src)]
    line = one_error_line(*cli([*base, "--task", "SocialNav"], capsys))
    assert "was trained on PointNav, not SocialNav" in line
    line = one_error_line(
        *cli([*base, "--config", json.dumps({**CFG, "lidar": {"beams": 48, "low_beams": 8}})], capsys)
    )
    assert "observes (61,), this run (85,)" in line
    line = one_error_line(*cli([*base, "--config", json.dumps(CFG)], capsys))  # the curbside protocol's 256 x 256
    assert "has a [32, 32] network, this run [256, 256]" in line
    line = one_error_line(*cli([*base, "--algo", "bc", "--demos", str(src)], capsys))
    assert "no demonstration dataset" in line or "--init-from fine-tunes PPO" in line
    line = one_error_line(*cli(["train", "run", "--out", str(tmp_path / "r2"), "--init-from", str(tmp_path)], capsys))
    assert "not a training run" in line


def test_demonstrations_mix_a_trained_policy_with_the_noisy_expert(tmp_path, capsys) -> None:
    from curbside.train.demos import collect_demos

    src = tmp_path / "ppo"
    train(
        "ppo",
        "PointNav",
        src,
        steps=64,
        env_config=CFG,
        n_envs=2,
        num_scenes=2,
        hparams=TINY,
        progress=False,
        subprocess=False,
    )
    mixed = collect_demos(
        "PointNav",
        tmp_path / "mixed",
        steps=400,
        env_config=CFG,
        num_scenes=2,
        progress=False,
        policy=src,
        policy_fraction=0.5,
    )
    assert 0 < mixed["policy_episodes"] < mixed["episodes"]  # both sources drove, per the episode's own draw
    again = collect_demos(
        "PointNav",
        tmp_path / "again",
        steps=400,
        env_config=CFG,
        num_scenes=2,
        progress=False,
        policy=src,
        policy_fraction=0.5,
    )
    assert (again["policy_episodes"], again["steps"]) == (mixed["policy_episodes"], mixed["steps"])  # deterministic
    line = one_error_line(*cli(["demos", "collect", "--policy-fraction", "0.8", "--out", str(tmp_path / "x")], capsys))
    assert "--policy-fraction needs --policy RUN" in line
    line = one_error_line(
        *cli(["demos", "collect", "--task", "SocialNav", "--policy", str(src), "--out", str(tmp_path / "x")], capsys)
    )
    assert "was trained on PointNav, not SocialNav" in line


def test_unknown_hyper_parameter_of_an_algorithm_names_the_valid_ones() -> None:
    with pytest.raises(ConfigError, match=r"unknown iql hyper-parameter\(s\) \['n_epochs'\]; valid: .*expectile"):
        resolve_run("iql", "PointNav", hparams={"n_epochs": 3})
    assert resolve_run("ppo", "PointNav", hparams={"n_steps": 64})["hparams"]["n_steps"] == 64


def test_target_kl_is_a_ppo_override_that_no_protocol_records() -> None:
    """target_kl reaches SB3's PPO only when given, so runs of a protocol resume under the values they recorded."""
    from curbside.train.online import ppo_kwargs

    assert "target_kl" not in resolve_run("ppo", "PointNav", protocol="paper_realistic")["hparams"]
    h = resolve_run("ppo", "PointNav", protocol="paper_realistic", hparams={"target_kl": 0.01})["hparams"]
    assert ppo_kwargs(h)["target_kl"] == 0.01
    for bad in (0, -0.01, "0.01", True):
        with pytest.raises(ConfigError, match=r"hparams.target_kl must be a number > 0"):
            resolve_run("ppo", "PointNav", hparams={"target_kl": bad})
    with pytest.raises(ConfigError, match=r"unknown bc hyper-parameter\(s\) \['target_kl'\]"):
        resolve_run("bc", "PointNav", hparams={"target_kl": 0.01})


def test_the_ray_executor_refuses_target_kl() -> None:
    pytest.importorskip("ray")
    from curbside.train.rllib import ppo_config

    h = resolve_run("ppo", "PointNav", hparams={"target_kl": 0.01})["hparams"]
    with pytest.raises(ConfigError, match="the ray executor has no target_kl"):
        ppo_config("ppo", "PointNav", {}, h, num_env_runners=1, envs_per_runner=1, num_scenes=4, seed=0)


def test_a_protocol_catalog_is_built_once_on_first_use(tmp_path, monkeypatch) -> None:
    """The paper_realistic protocol names a 1,023-asset catalog (31 variants of each of the 33 categories); a protocol's catalog
    is built the first time an env of the protocol is configured, and scenes then draw its assets."""
    import dataclasses

    from catalogs.reader import CatalogReader
    from curbside.train.envs import split_config
    from curbside.train.protocols import PAPER_CATALOG, CatalogRecipe
    from retrieval.procedural import category_names
    from sim.envs.pointnav import PointNavEnv

    realistic = protocol("paper_realistic")
    assert realistic.catalog == PAPER_CATALOG and realistic.env_config["catalog"] == PAPER_CATALOG.path
    assert PAPER_CATALOG.variants >= 30 and PAPER_CATALOG.variants * len(category_names()) >= 1_000

    recipe = CatalogRecipe(str(tmp_path / "tiny.duckdb"), variants=1)
    tiny = dataclasses.replace(protocol("curbside"), name="tiny", catalog=recipe, env_config={"catalog": recipe.path})
    monkeypatch.setitem(PROTOCOLS, "tiny", tiny)
    cfg = split_config({**CFG, **tiny.env_config}, "train", 2)
    assert len(CatalogReader(recipe.path)) == len(category_names())
    stamp = Path(recipe.path).stat().st_mtime_ns
    split_config(cfg, "test", 2)
    assert Path(recipe.path).stat().st_mtime_ns == stamp  # built once
    env = PointNavEnv(cfg)
    env.reset(seed=0)
    assert {o["asset_id"] for o in env.scene_spec["objects"]} & set(CatalogReader(recipe.path).table.asset_id)
    env.close()


@pytest.mark.parametrize("task", ["PointNav", "SocialNav"])
def test_batched_evaluation_runs_the_pybullet_evaluations_episodes(task) -> None:
    # A policy driving ahead at a constant command, on the PyBullet env and on the batched env: episode k has seed k
    # on both, so the same scenes and routes; the two simulators' contacts differ by a few steps, not by episodes.
    from curbside.train.evaluate import evaluate_policy, evaluate_policy_batched

    cfg, action = {**CFG, "horizon": 60}, np.array([0.2, 0.6], dtype=np.float32)
    ref = evaluate_policy(lambda o: action, task, cfg, episodes=3, num_scenes=3, progress=False)
    got = evaluate_policy_batched(
        lambda obs: np.tile(action, (len(obs), 1)), cfg, task=task, episodes=3, num_scenes=3, n_envs=3
    )
    assert got["episodes"] == 3 and got["env"] == "batched"
    assert got["sr"] == ref["sr"]
    assert 0.0 < got["route_completion"] and abs(got["route_completion"] - ref["route_completion"]) < 0.1
    assert ("sns" in got) == (task == "SocialNav")
    if task == "SocialNav":
        assert got["sns"] == pytest.approx(ref["sns"], abs=0.1)
    with pytest.raises(ConfigError, match="valid: PointNav, SocialNav"):
        evaluate_policy_batched(lambda obs: obs[:, :2], cfg, task="Teleop", episodes=1)
