"""The experiment runner and report: every shipped file loads, a killed experiment resumes without redoing finished
runs, the report writes its columns (`report.COLUMNS`) beside the paper's numbers; bad input is one line,
exit 2."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from curbside.experiments.report import COLUMNS, paper_cell, write_report
from curbside.experiments.runner import run_experiment
from curbside.experiments.spec import load_experiment, names
from kernel.config import ConfigError
from tests.helpers import cli, one_error_line

CFG = {"lidar": {"beams": 24, "low_beams": 8}, "route_length": [5.0, 25.0], "scene": {"blocks": 1}}
TINY = {
    "online_steps": 128,
    "episodes": 1,
    "n_envs": 2,
    "scenes": 2,
    "backend": "pybullet",
    "hparams": {"n_steps": 64, "batch_size": 64, "n_epochs": 1, "net_arch": [32, 32]},
}


def test_every_shipped_experiment_loads_with_its_paper_numbers() -> None:
    assert {
        "table1_paper",
        "table2",
        "table5_horizon",
        "table5_pedestrians",
        "ablation_generalisation",
        "ablation_scaling",
        "ablation_static_density",
        "ablation_dynamic_density",
        "seed_robustness",
    } <= set(names())
    t1 = load_experiment("table1_paper")
    assert len(t1.runs) == 14 and sum(len(r.seeds) for r in t1.runs) == 18 and t1.protocol == "paper_realistic"
    cells = {(r.task, s, r.method) for r in t1.runs for s in r.evaluate}
    assert len(cells) == 28 and all(paper_cell(t1, t, m, s, "") for t, s, m in cells)
    t2 = load_experiment("table2")
    assert all(paper_cell(t2, r.task, r.method, "test", r.setting) for r in t2.runs)
    scaling = load_experiment("ablation_scaling")
    assert [int(r.setting) for r in scaling.runs] == [5, 50, 200, 1000]
    # Each run draws at least as many scenes as it counts in its budget (one draw every scene_steps env steps).
    from curbside.experiments.spec import budget_of

    small = budget_of(scaling, "small")
    assert all(small["online_steps"] // r.env["scene_steps"] >= r.env["num_scenes"] for r in scaling.runs)


def _experiment(tmp_path: Path) -> Path:
    spec = {
        "name": "tiny",
        "title": "tiny",
        "paper": "table1",
        "protocol": "curbside",
        "evaluate": ["test"],
        "runs": [
            {"id": "a", "task": "PointNav", "method": "ppo", "seeds": [0, 1], "env": CFG},
            {
                "id": "b",
                "task": "PointNav",
                "method": "ppo",
                "seeds": [0, 1],
                "init": "a",
                "train": False,
                "evaluate": ["unseen"],
            },
        ],
        "budgets": {"smoke": TINY},
    }
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def test_a_killed_experiment_resumes_without_redoing_finished_runs(tmp_path, monkeypatch) -> None:
    import curbside.train.run as run_module

    real = run_module.train
    calls: list[tuple[str, int]] = []

    def killed_on_second(algo, task, out, **kw):
        calls.append((Path(out).parent.name, kw["seed"]))
        if len(calls) == 2:
            raise KeyboardInterrupt  # the run is killed while training seed 1
        return real(algo, task, out, **kw)

    exp, root = _experiment(tmp_path), tmp_path / "runs"
    monkeypatch.setattr(run_module, "train", killed_on_second)
    with pytest.raises(KeyboardInterrupt):
        run_experiment(str(exp), "smoke", root=root, progress=False, log=lambda s: None)
    first = root / "tiny" / "smoke" / "a" / "seed_0" / "result.json"
    assert first.is_file() and not (root / "tiny" / "smoke" / "a" / "seed_1" / "result.json").exists()
    stamp = first.stat().st_mtime_ns

    calls.clear()
    monkeypatch.setattr(
        run_module, "train", lambda *a, **kw: (calls.append((Path(a[2]).parent.name, kw["seed"])), real(*a, **kw))[1]
    )
    results = run_experiment(str(exp), "smoke", root=root, progress=False, log=lambda s: None)
    assert calls == [("a", 1)]  # only the killed run trains again; b evaluates a's policies without training
    assert first.stat().st_mtime_ns == stamp and len(results) == 4
    assert {r["run"]: r["steps"] for r in results} == {"a": 128, "b": 0}

    # Evaluated again (after a simulator fix, say): every finished run's figures measured anew, nothing trained.
    tampered = json.loads(first.read_text())
    measured = tampered["evals"]["test"]["sr"]
    tampered["evals"]["test"]["sr"] = 9.0
    first.write_text(json.dumps(tampered))
    calls.clear()
    again = run_experiment(str(exp), "smoke", root=root, reevaluate=True, progress=False, log=lambda s: None)
    assert calls == [] and len(again) == 4
    assert json.loads(first.read_text())["evals"]["test"]["sr"] == measured
    assert {r["run"]: r["train_s"] for r in again} == {r["run"]: r["train_s"] for r in results}

    # The protocol's rule turns to sampled actions: every finished run is evaluated again with draws, nothing trained;
    # a run after that finds them current and evaluates nothing.
    from dataclasses import replace

    from curbside.train.protocols import PROTOCOLS

    with monkeypatch.context() as m:
        m.setitem(PROTOCOLS, "curbside", replace(PROTOCOLS["curbside"], eval_actions="sampled"))
        logged: list[str] = []
        sampled = run_experiment(str(exp), "smoke", root=root, progress=False, log=logged.append)
        assert calls == [] and len(sampled) == 4
        assert {ev["actions"] for r in sampled for ev in r["evals"].values()} == {"sampled"}
        assert sum("evaluated with mean actions; the protocol's are sampled" in line for line in logged) == 4
        stamp = first.stat().st_mtime_ns
        run_experiment(str(exp), "smoke", root=root, progress=False, log=lambda s: None)
        assert first.stat().st_mtime_ns == stamp
    run_experiment(str(exp), "smoke", root=root, progress=False, log=lambda s: None)  # back to mean actions
    assert {ev["actions"] for ev in json.loads(first.read_text())["evals"].values()} == {"mean"}

    # The protocol's episode rules for evaluations change (a 7-step horizon here): the report leaves the runs
    # evaluated under the old rules out until `run` evaluates them again under the new ones, training nothing.
    with monkeypatch.context() as m:
        m.setitem(PROTOCOLS, "curbside", replace(PROTOCOLS["curbside"], eval_env={"horizon": 7}))
        out = write_report(str(exp), "smoke", root=root, out_root=tmp_path / "rules")
        assert len(json.loads((out.parent / "report.json").read_text())["runs_evaluated_otherwise"]) == 4
        assert out.read_text().strip() == ",".join(COLUMNS)  # no rows
        from curbside.experiments.release import release

        skipped: list[str] = []  # a card's figures would not be the protocol's
        assert release(str(exp), "smoke", root=root, zoo=tmp_path / "zoo", log=skipped.append) == []
        assert skipped == [
            'skipped a seed 0: evaluated under episode rules {}; the protocol\'s are {"horizon": 7}; `curbside '
            f"experiment run {exp} --budget smoke` measures it again first"
        ]
        logged = []
        ruled = run_experiment(str(exp), "smoke", root=root, progress=False, log=logged.append)
        assert (
            calls == [] and sum('under episode rules {}; the protocol\'s are {"horizon": 7}' in x for x in logged) == 4
        )
        assert [ev["eval_env"] for r in ruled for ev in r["evals"].values()] == [{"horizon": 7}] * 4
        assert max(ev["steps"] for r in ruled for ev in r["evals"].values()) <= 7  # the rule reached the env
        out = write_report(str(exp), "smoke", root=root, out_root=tmp_path / "rules")
        assert json.loads((out.parent / "report.json").read_text())["runs_evaluated_otherwise"] == {}
    run_experiment(str(exp), "smoke", root=root, progress=False, log=lambda s: None)  # back to the env's own rules
    assert {json.dumps(ev["eval_env"]) for ev in json.loads(first.read_text())["evals"].values()} == {"{}"}

    out = write_report(str(exp), "smoke", root=root, out_root=tmp_path / "report")
    with open(out, newline="") as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == COLUMNS and len(rows) == 4
    assert {(r["split"], r["paper_sr"]) for r in rows} == {("test", "0.66"), ("unseen", "0.49")}
    assert (out.parent / "results.png").stat().st_size > 0
    assert json.loads((out.parent / "report.json").read_text())["runs_finished"] == 4
    with open(out.parent / "summary.csv", newline="") as f:
        summary = {(r["method"], r["setting"], r["split"]): r for r in csv.DictReader(f)}
    for key, cell in summary.items():  # each run and split: the seeds' mean and std
        srs = [float(r["sr"]) for r in rows if (r["method"], r["setting"], r["split"]) == key]
        assert cell["seeds"].split() == sorted(
            {r["seed"] for r in rows if (r["method"], r["setting"], r["split"]) == key}
        )
        assert float(cell["sr_mean"]) == pytest.approx(np.mean(srs), abs=1e-4)
        assert float(cell["sr_std"]) == pytest.approx(np.std(srs), abs=1e-4)
    assert sum(len(c["seeds"].split()) for c in summary.values()) == len(rows)

    # The budget asks for more episodes a split: the report leaves the runs measured on fewer out until `run`
    # evaluates them again on the new count, training nothing.
    more = yaml.safe_load(exp.read_text())
    more["budgets"]["smoke"]["episodes"] = 2
    exp.write_text(yaml.safe_dump(more))
    out = write_report(str(exp), "smoke", root=root, out_root=tmp_path / "more")
    assert set(json.loads((out.parent / "report.json").read_text())["runs_evaluated_otherwise"].values()) == {
        "on 1 episodes a split; the budget's are 2"
    }
    logged = []
    recounted = run_experiment(str(exp), "smoke", root=root, progress=False, log=logged.append)
    assert calls == [] and sum("on 1 episodes a split; the budget's are 2" in x for x in logged) == 4
    assert [ev["episodes"] for r in recounted for ev in r["evals"].values()] == [2] * 4
    out = write_report(str(exp), "smoke", root=root, out_root=tmp_path / "more")
    assert json.loads((out.parent / "report.json").read_text())["runs_finished"] == 4

    # Evaluation shared among processes: the same episodes, so the same figures.
    from curbside.train.evaluate import evaluate_run

    source = root / "tiny" / "smoke" / "a" / "seed_0"
    one, two = (
        evaluate_run(source, "PointNav", CFG, split="test", episodes=3, num_scenes=2, workers=w, progress=False)
        for w in (1, 2)
    )
    assert one == two and one["episodes"] == 3
    # Sampled actions: torch is seeded with each episode's seed, so the split among processes changes nothing.
    one, two = (
        evaluate_run(
            source,
            "PointNav",
            CFG,
            split="test",
            episodes=3,
            num_scenes=2,
            workers=w,
            progress=False,
            actions="sampled",
        )
        for w in (1, 2)
    )
    assert one == two and one["episodes"] == 3
    with pytest.raises(ConfigError, match="unknown actions 'greedy'; valid: mean, sampled"):
        evaluate_run(source, "PointNav", CFG, episodes=1, actions="greedy")

    # A training run that evaluates itself with draws keeps its own: torch's generator is given back its state.
    import torch

    from curbside.train.evaluate import evaluate_policy

    def draw(obs):
        return torch.rand(2).numpy() * 2 - 1

    torch.manual_seed(7)
    state = torch.get_rng_state()
    drawn = [
        evaluate_policy(draw, "PointNav", CFG, episodes=2, num_scenes=2, progress=False, seed_torch=True)
        for _ in range(2)
    ]
    assert drawn[0] == drawn[1] and torch.equal(torch.get_rng_state(), state)

    # The zoo: run a's seed-0 policy (b only evaluates it), loadable as it is, with a card and no Adam moments.
    from curbside.experiments.release import release
    from curbside.train.policies import load_policy

    zoo = tmp_path / "zoo"
    assert release(str(exp), "smoke", root=root, zoo=zoo, only=["b"]) == []  # b trains nothing: no policy of its own
    with pytest.raises(ConfigError, match="unknown run id"):
        release(str(exp), "smoke", root=root, zoo=zoo, only=["c"])
    assert release(str(exp), "smoke", root=root, zoo=zoo) == [zoo / "curbside" / "PointNav" / "ppo"]
    released, source = zoo / "curbside" / "PointNav" / "ppo", root / "tiny" / "smoke" / "a" / "seed_0"
    card = json.loads((released / "card.json").read_text())
    assert card["steps"] == 128 and card["seed"] == 0 and card["protocol"] == "curbside"
    assert set(card["metrics"]) == {"test"} and 0.0 <= card["metrics"]["test"]["sr"] <= 1.0
    assert (released / "policy.zip").stat().st_size < (source / "policy.zip").stat().st_size
    from stable_baselines3 import PPO

    dim = PPO.load(source / "policy.zip", device="cpu").observation_space.shape[0]
    obs = np.random.default_rng(0).uniform(-1, 1, (5, dim)).astype(np.float32)
    ours, theirs = load_policy(released)[0], load_policy(source)[0]
    assert all(np.array_equal(ours(o), theirs(o)) for o in obs)

    # The protocol changes (a scene setting, a new catalog, a hyper-parameter): the finished runs are stale. The
    # report leaves them (and b's evaluations of them) out; the runner moves them aside and trains them again.
    import dataclasses

    from curbside.train import protocols

    hparams = {**protocols.PROTOCOLS["curbside"].hparams, "ppo": {**protocols.PROTOCOLS["curbside"].hparams["ppo"]}}
    hparams["ppo"]["gamma"] = 0.98
    changed = dataclasses.replace(protocols.PROTOCOLS["curbside"], env_config={"horizon": 777}, hparams=hparams)
    monkeypatch.setitem(protocols.PROTOCOLS, "curbside", changed)
    out = write_report(str(exp), "smoke", root=root, out_root=tmp_path / "report")
    report = json.loads((out.parent / "report.json").read_text())
    stale = ["env_config.horizon", "hparams.gamma"]
    assert report["runs_stale"] == {"a seed 0": stale, "a seed 1": stale}
    assert out.read_text().strip() == ",".join(COLUMNS)  # no rows
    calls.clear()
    run_experiment(str(exp), "smoke", root=root, seeds=[0], progress=False, log=lambda s: None)
    assert calls == [("a", 0)]
    assert (root / "tiny" / "smoke" / "stale" / "a" / "seed_0" / "result.json").is_file()
    assert (root / "tiny" / "smoke" / "stale" / "b" / "seed_0" / "result.json").is_file()  # b evaluated the old a
    retrained = json.loads((source / "run.json").read_text())
    assert retrained["env_config"]["horizon"] == 777 and retrained["hparams"]["gamma"] == 0.98
    with open(write_report(str(exp), "smoke", root=root, out_root=tmp_path / "report"), newline="") as f:
        rows = list(csv.DictReader(f))
    assert sorted((r["seed"], r["steps"]) for r in rows) == [("0", "0"), ("0", "128")]  # a and b, seed 0 alone


def test_bad_experiment_input_is_one_line_exit_2(tmp_path, capsys) -> None:
    line = one_error_line(*cli(["experiment", "run", "table9"], capsys))
    assert "unknown experiment 'table9'; valid: ablation_dynamic_density" in line
    line = one_error_line(*cli(["experiment", "run", "table1_paper", "--budget", "huge"], capsys))
    assert "unknown budget 'huge'; valid: smoke, small, paper" in line
    for verb in ("pack", "unpack"):
        line = one_error_line(*cli(["experiment", verb, "table1_paper", "--budget", "huge"], capsys))
        assert "unknown budget 'huge'; valid: smoke, small, paper" in line
    line = one_error_line(*cli(["experiment", "run", "table1_paper", "--only", "PointNav-dqn"], capsys))
    assert "unknown run id(s) ['PointNav-dqn']" in line
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"name": "bad", "runs": [{"task": "PointNav", "method": "ppo", "sedes": [1]}]}))
    line = one_error_line(*cli(["experiment", "report", str(bad)], capsys))
    assert "unknown key(s) 'sedes'" in line and "seeds" in line
    bad.write_text("runs: [ {task: PointNav")
    line = one_error_line(*cli(["experiment", "run", str(bad), "--budget", "smoke"], capsys))
    assert "is not valid YAML" in line
    bad.write_text(yaml.safe_dump({"name": "bad", "runs": [{"task": "PointNav", "method": "ppo", "init": "later"}]}))
    with pytest.raises(ConfigError, match="must name an earlier run"):
        load_experiment(str(bad))


def _results(root: Path, name: str, rows: list[tuple[str, str, str, str, float, float]]) -> None:
    (root / name).mkdir(parents=True, exist_ok=True)
    with open(root / name / "results.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(COLUMNS))
        writer.writeheader()
        for task, method, split, setting, sr, cost in rows:
            writer.writerow(
                {
                    "experiment": name,
                    "task": task,
                    "method": method,
                    "split": split,
                    "setting": setting,
                    "seed": 0,
                    "steps": 1,
                    "sr": sr,
                    "spl": sr,
                    "sns": "",
                    "cost": cost,
                }
            )


def test_findings_follow_the_results_and_say_what_has_not_run(tmp_path) -> None:
    from curbside.experiments.findings import write_findings

    methods = ("ppo", "ppo_lag", "ppo_et", "iql", "td3bc", "bc", "gail")
    rows = []
    for k, m in enumerate(methods):
        for task, scale in (("PointNav", 1.0), ("SocialNav", 0.5)):
            rows += [
                (task, m, "test", "", scale * (0.6 - 0.05 * k), 1.0 - 0.1 * k),
                (task, m, "unseen", "", scale * (0.5 - 0.05 * k), 1.0),
            ]
    _results(tmp_path, "table1_paper", rows)
    _results(
        tmp_path,
        "ablation_scaling",
        [("PointNav", "ppo", "test", n, sr, 1.0) for n, sr in (("5", 0.3), ("50", 0.2), ("1000", 0.1))],
    )
    data = json.loads(write_findings(tmp_path).read_text())
    state = {f["finding"]: f["reproduced"] for f in data["findings"]}
    assert state[1] and state[2] and state[3] and state[4]  # below 0.8; unseen lower; SocialNav half; safe RL
    assert state[5] is False  # test SR falls with more scenes here
    five = next(f for f in data["findings"] if f["finding"] == 5)
    assert (
        five["why"]
        == "test SR at 1000 scenes, 0.10, is not above 0.30 at 5; test SR falls over log(scenes) (slope -0.038)."
    )
    assert all("why" not in f for f in data["findings"] if f["reproduced"])
    assert [n for n, v in state.items() if v is None] == [6, 7, 8, 9, 10]
    assert data["reproduced"] == 4 and data["not_reproduced"] == 1 and data["not_run"] == 5
    missing = next(f for f in data["findings"] if f["finding"] == 9)
    assert "curbside experiment run table5_horizon --budget small" in missing["why"]
    assert data["paper_budget_cells"] == []
    # Finding 6 reads two experiments: with ablation (c) measured, it waits for ablation (d), the one with no cells.
    _results(
        tmp_path,
        "ablation_static_density",
        [("PointNav", "ppo", split, d, 0.4, 1.0) for split in ("train", "test") for d in ("0.01", "1.0")],
    )
    six = next(f for f in json.loads(write_findings(tmp_path).read_text())["findings"] if f["finding"] == 6)
    assert six["reproduced"] is None
    assert "curbside experiment run ablation_dynamic_density --budget small" in six["why"]

    # PPO PointNav at the paper's budget stands in for its small cells where a finding reads PPO's own level: here
    # its unseen SR is above test. Its cost (0.1, below PPO-Lag's 0.9) stays out of finding 4, which compares the
    # methods at the budget they share.
    _results(
        tmp_path / "table1_paper",
        "paper",
        [("PointNav", "ppo", "test", "", 0.4, 0.1), ("PointNav", "ppo", "unseen", "", 0.45, 1.0)],
    )
    data = json.loads(write_findings(tmp_path).read_text())
    two = next(f for f in data["findings"] if f["finding"] == 2)
    assert two["reproduced"] is False and two["ours"] == {"ppo_pointnav_test_sr": 0.4, "ppo_pointnav_unseen_sr": 0.45}
    assert two["why"] == "PPO's PointNav unseen SR 0.45 is not below its test SR 0.40."
    four = next(f for f in data["findings"] if f["finding"] == 4)
    assert four["reproduced"] is True and four["ours"]["PointNav_ppo_lag"]["ppo_cost"] == 1.0
    three = next(f for f in data["findings"] if f["finding"] == 3)
    assert three["ours"]["ppo"]["PointNav"] == 0.6
    assert data["paper_budget_cells"] == ["table1_paper PointNav ppo test", "table1_paper PointNav ppo unseen"]


def test_seeds_and_only_pick_the_runs_to_train(tmp_path, capsys) -> None:
    exp, root = _experiment(tmp_path), tmp_path / "runs"
    results = run_experiment(str(exp), "smoke", root=root, only=["a"], seeds=[1], progress=False, log=lambda s: None)
    assert [(r["run"], r["seed"]) for r in results] == [("a", 1)]
    assert not (root / "tiny" / "smoke" / "a" / "seed_0").exists()
    line = one_error_line(*cli(["experiment", "run", str(exp), "--budget", "smoke", "--seeds", "one"], capsys))
    assert "--seeds must be comma-separated integers" in line


def test_a_run_is_current_once_finished_and_trained_once_for_every_experiment(tmp_path) -> None:
    """Ablation (b)'s runs give their scene count in their env config: the run records it once (as num_scenes), so
    the report counts it finished, not stale, and a second `run` trains nothing. Another experiment that would train
    the same run copies its training instead."""
    spec = {
        "name": "scaled",
        "title": "scaled",
        "paper": "ablation_scaling",
        "protocol": "curbside",
        "evaluate": ["test"],
        "runs": [
            {"id": "scenes-3", "task": "PointNav", "method": "ppo", "setting": "3", "env": {**CFG, "num_scenes": 3}}
        ],
        "budgets": {"smoke": TINY},
    }
    exp, root = tmp_path / "scaled.yaml", tmp_path / "runs"
    exp.write_text(yaml.safe_dump(spec))
    run_experiment(str(exp), "smoke", root=root, progress=False, log=lambda s: None)
    recorded = json.loads((root / "scaled" / "smoke" / "scenes-3" / "seed_0" / "run.json").read_text())
    assert recorded["num_scenes"] == 3 and "num_scenes" not in recorded["env_config"]
    out = write_report(str(exp), "smoke", root=root, out_root=tmp_path / "report")
    report = json.loads((out.parent / "report.json").read_text())
    assert report["runs_stale"] == {} and report["runs_finished"] == 1
    logged: list[str] = []
    run_experiment(str(exp), "smoke", root=root, progress=False, log=logged.append)
    assert not any("training" in line for line in logged)

    # Another experiment with the same training copies it (and evaluates on its own splits); one scene fewer trains.
    runs = [{**spec["runs"][0], "id": "same"}, {**spec["runs"][0], "id": "fewer", "env": {**CFG, "num_scenes": 2}}]
    other = tmp_path / "other.yaml"
    other.write_text(
        yaml.safe_dump(json.loads(json.dumps({**spec, "name": "other", "evaluate": ["unseen"], "runs": runs})))
    )
    logged.clear()
    results = {r["run"]: r for r in run_experiment(str(other), "smoke", root=root, progress=False, log=logged.append)}
    source, copy = root / "scaled" / "smoke" / "scenes-3" / "seed_0", root / "other" / "smoke" / "same" / "seed_0"
    assert results["same"]["trained_in"] == str(source) and "trained_in" not in results["fewer"]
    assert [line.split(": ")[0] for line in logged if "training" in line] == [
        "[other smoke] same seed 0",  # trained as scenes-3 was; copying its training
        "[other smoke] fewer seed 0",  # training ppo ...
    ]
    assert (copy / "policy.zip").read_bytes() == (source / "policy.zip").read_bytes()
    assert set(results["same"]["evals"]) == {"unseen"}


def test_demonstrations_follow_the_best_finished_ppo_of_the_task(tmp_path) -> None:
    from curbside.experiments.runner import _demo_policy, run_dir
    from curbside.experiments.spec import load_experiment

    def finish(d: Path, sr: float) -> Path:
        d.mkdir(parents=True)
        (d / "result.json").write_text(json.dumps({"evals": {"test": {"sr": sr}, "unseen": {"sr": 0.5}}}))
        return d

    exp = load_experiment("table1_paper")
    ppo = {t: next(r for r in exp.runs if r.task == t and r.method == "ppo") for t in ("PointNav", "SocialNav")}
    assert _demo_policy(tmp_path, exp, "PointNav") is None  # no PPO has finished: the expert drives every episode
    for budget in ("smoke", "small", "paper"):
        d = finish(run_dir(tmp_path, exp, budget, ppo["PointNav"], 0), 0.1)
        # the largest finished budget drives, whatever budget the demonstrations are collected for
        assert _demo_policy(tmp_path, exp, "PointNav") == d
    assert _demo_policy(tmp_path, exp, "SocialNav") is None  # each task's own PPO

    # A PPO that succeeds in fewer than a tenth of its test episodes drives none: the largest budget that did, or
    # the expert alone.
    finish(run_dir(tmp_path, exp, "paper", ppo["SocialNav"], 0), 0.02)
    assert _demo_policy(tmp_path, exp, "SocialNav") is None
    small = finish(run_dir(tmp_path, exp, "small", ppo["SocialNav"], 0), 0.1)
    assert _demo_policy(tmp_path, exp, "SocialNav") == small


def test_an_offline_run_is_stale_once_another_ppo_drives_its_demonstrations(tmp_path) -> None:
    """The demonstrations an offline run learned from are part of its training: when a PPO of the task finishes at a
    larger budget and drives them now, the run's recorded source differs and the report and runner count it stale."""
    from curbside.experiments.report import stale_runs
    from curbside.experiments.runner import demo_source, expected_training, run_dir
    from curbside.experiments.spec import load_experiment

    exp = load_experiment("table1_paper")
    run = next(r for r in exp.runs if r.task == "SocialNav" and r.method == "iql")
    ppo = next(r for r in exp.runs if r.task == "SocialNav" and r.method == "ppo")
    expected = expected_training(exp, run, "small", tmp_path)
    assert expected["demos"] == {"policy": None, "policy_fraction": 0.0, "noise": expected["demos"]["noise"]}
    out = run_dir(tmp_path, exp, "small", run, 0)
    out.mkdir(parents=True)
    recorded = {"env_config": expected["env_config"], "hparams": expected["hparams"]}
    # run.json records the demonstrations with their statistics too; those are not compared
    recorded["demos_meta"] = {**expected["demos"], "episodes": 30, "success_rate": 0.17}
    (out / "run.json").write_text(json.dumps(recorded))
    (out / "result.json").write_text(json.dumps({"evals": {"test": {"sr": 0.5}}}))
    assert stale_runs(exp, "small", tmp_path) == {}

    driver = run_dir(tmp_path, exp, "paper", ppo, 0)
    driver.mkdir(parents=True)
    (driver / "result.json").write_text(json.dumps({"evals": {"test": {"sr": 0.3}}}))
    assert demo_source(tmp_path, exp, "SocialNav")["policy"] == str(driver)
    assert stale_runs(exp, "small", tmp_path) == {"SocialNav-iql seed 0": ["demos.policy", "demos.policy_fraction"]}


def test_an_offline_run_trains_again_once_a_ppo_of_its_task_drives_the_demonstrations(tmp_path, monkeypatch) -> None:
    """`run` moves an offline run whose demonstrations another source drove aside and trains it again on new ones:
    the experiment's PPO, failing every test episode when the run trained (the expert drove alone), is found
    succeeding since."""
    import dataclasses

    import curbside.train.run as run_module
    from curbside.train import protocols

    base = protocols.PROTOCOLS["curbside"]
    mixed = dataclasses.replace(base, demos=dataclasses.replace(base.demos, policy_fraction=0.5))
    monkeypatch.setitem(protocols.PROTOCOLS, "curbside", mixed)
    spec = {
        "name": "mixed",
        "title": "mixed",
        "paper": "table1",
        "protocol": "curbside",
        "evaluate": ["test"],
        "runs": [
            {"id": "p", "task": "PointNav", "method": "ppo", "seeds": [0], "env": CFG},
            {"id": "o", "task": "PointNav", "method": "bc", "seeds": [0], "env": CFG},
        ],
        "budgets": {"smoke": {**TINY, "bc_steps": 20, "demos_steps": 200}},
    }
    path = tmp_path / "mixed.yaml"
    path.write_text(yaml.safe_dump(json.loads(json.dumps(spec))))  # no YAML aliases for the shared CFG
    real, calls = run_module.train, []
    monkeypatch.setattr(run_module, "train", lambda *a, **kw: (calls.append(Path(a[2]).parent.name), real(*a, **kw))[1])
    root = tmp_path / "runs"
    ppo_result = root / "mixed" / "smoke" / "p" / "seed_0" / "result.json"

    def ppo_scores(sr: float) -> None:
        result = json.loads(ppo_result.read_text())
        result["evals"]["test"]["sr"] = sr
        ppo_result.write_text(json.dumps(result))

    run_experiment(str(path), "smoke", root=root, only=["p"], progress=False, log=lambda s: None)
    ppo_scores(0.0)
    run_experiment(str(path), "smoke", root=root, only=["o"], progress=False, log=lambda s: None)
    offline = root / "mixed" / "smoke" / "o" / "seed_0"
    first = json.loads((offline / "run.json").read_text())["demos_meta"]
    assert first["policy"] is None and first["policy_fraction"] == 0.0 and calls == ["p", "o"]
    run_experiment(str(path), "smoke", root=root, only=["o"], progress=False, log=lambda s: None)
    assert calls == ["p", "o"]  # the same source: nothing to do

    ppo_scores(0.5)
    logged: list[str] = []
    run_experiment(str(path), "smoke", root=root, only=["o"], progress=False, log=logged.append)
    assert calls == ["p", "o", "o"]
    assert any("(demos.policy, demos.policy_fraction)" in line for line in logged), logged
    assert (root / "mixed" / "smoke" / "stale" / "o" / "seed_0" / "result.json").is_file()
    again = json.loads((offline / "run.json").read_text())["demos_meta"]
    assert again["policy"] == str(ppo_result.parent) and again["policy_fraction"] == 0.5


def test_packed_runs_go_on_on_another_machine(tmp_path, monkeypatch) -> None:
    """A run killed before its result is packed with its newest checkpoint alone and resumes from it after unpack;
    a finished run travels with a compact policy and is never trained again."""
    import shutil
    import subprocess
    import sys
    import time

    import torch

    import curbside.train.online as online
    import curbside.train.run as run_module
    from curbside.experiments.archive import pack, unpack

    real = run_module.train
    calls: list[bool] = []

    def killed_after_training(algo, task, out, **kw):
        real(algo, task, out, **kw)
        raise KeyboardInterrupt  # killed before its evaluation: no result.json

    spec = yaml.safe_load(_experiment(tmp_path).read_text())
    spec["runs"] = spec["runs"][:1]
    spec["runs"][0]["seeds"] = [0]
    spec["budgets"]["smoke"]["online_steps"] = 256  # two rollouts: the newest checkpoint holds an update's moments
    exp = tmp_path / "tiny.yaml"
    exp.write_text(yaml.safe_dump(spec))
    root, archive, moved = tmp_path / "runs", tmp_path / "archive", tmp_path / "elsewhere"
    monkeypatch.setattr(online, "CHECKPOINT_EVERY", 64)
    monkeypatch.setattr(run_module, "train", killed_after_training)
    with pytest.raises(KeyboardInterrupt):
        run_experiment(str(exp), "smoke", root=root, progress=False, log=lambda s: None)
    source = root / "tiny" / "smoke" / "a" / "seed_0"
    assert len(list((source / "checkpoints").iterdir())) == 4  # every 64 steps

    assert pack(str(exp), "smoke", root=root, archive=archive) == [archive / "tiny" / "smoke" / "a" / "seed_0"]
    packed = archive / "tiny" / "smoke" / "a" / "seed_0"
    assert [f.name for f in (packed / "checkpoints").iterdir()] == ["policy_256_steps.zip"]
    assert (packed / "run.json").is_file() and not (packed / "result.json").exists()

    shutil.copytree(archive, moved / "archive")  # another machine: the archive alone, no runs
    monkeypatch.setattr(run_module, "train", lambda *a, **kw: (calls.append(kw["resume"]), real(*a, **kw))[1])
    assert unpack(str(exp), "smoke", root=moved / "runs", archive=moved / "archive") == (
        [moved / "runs" / "tiny" / "smoke" / "a" / "seed_0"],
        [],
    )
    (result,) = run_experiment(str(exp), "smoke", root=moved / "runs", progress=False, log=lambda s: None)
    assert calls == [True] and result["resumed"] and result["steps"] == 256
    from stable_baselines3 import PPO

    resumed = moved / "runs" / "tiny" / "smoke" / "a" / "seed_0"
    assert PPO.load(resumed / "policy.zip", device="cpu").num_timesteps == 256  # nothing trained past the checkpoint

    # Finished: the result and a policy without Adam's moments travel; unpacked, the run is done and evaluates alike.
    pack(str(exp), "smoke", root=moved / "runs", archive=archive)
    assert (packed / "result.json").is_file() and not (packed / "checkpoints").exists()
    compact, whole = (PPO.load(d / "policy.zip", device="cpu").policy for d in (packed, resumed))
    assert compact.optimizer.state_dict()["state"] == {} and whole.optimizer.state_dict()["state"] != {}
    assert all(torch.equal(a, b) for a, b in zip(compact.state_dict().values(), whole.state_dict().values()))
    # Repacked by another process, later, an unchanged run is the same bytes: nothing churns in git.
    first_bytes = (packed / "policy.zip").read_bytes()
    time.sleep(2.1)  # past the zip format's 2-second time resolution
    repack = f"from curbside.experiments.archive import pack; pack({str(exp)!r}, 'smoke', root={str(moved / 'runs')!r}, archive={str(archive)!r})"
    subprocess.run([sys.executable, "-c", repack], check=True)
    assert (packed / "policy.zip").read_bytes() == first_bytes
    calls.clear()
    third = tmp_path / "third"
    unpack(str(exp), "smoke", root=third, archive=archive)
    (again,) = run_experiment(str(exp), "smoke", root=third, progress=False, log=lambda s: None)
    assert calls == [] and again == result
    restored, kept = unpack(str(exp), "smoke", root=third, archive=archive)
    assert restored == [] and kept == [third / "tiny" / "smoke" / "a" / "seed_0"]


def test_every_table2_run_draws_a_route_on_its_single_block() -> None:
    # One block holds tens of metres of sidewalk: a run that kept the protocol's paper-scale routes could not start.
    import gymnasium as gym

    from curbside.train.protocols import deep_merge, protocol

    t2 = load_experiment("table2")
    proto = protocol(t2.protocol)
    for run in t2.runs:
        cfg = deep_merge(deep_merge(proto.env_config, run.env), run.eval_env)
        cfg.pop("catalog")  # built by `dvc repro`, not in a clean clone; the route does not depend on the assets
        env = gym.make(f"curbside/{run.task}-v0", config={**cfg, "split": "test"})
        try:
            _, info = env.reset(seed=0)
            lo, hi = cfg["route_length"]
            assert lo <= info["route_length"] <= hi, (run.id, info["route_length"])
        finally:
            env.close()


def test_static_density_runs_scale_the_street_objects_with_their_setting() -> None:
    # The metaurban12k preset's min_objects floor refills sparse scenes: a run that kept it trained its "1 %" on
    # ~30 % of the full density's street objects, and the ablation measured almost no range of densities.
    import warnings

    from curbside.train.protocols import deep_merge, protocol
    from sim.scene.generator import generate_scene
    from sim.tasks.pointnav import DEFAULT_CONFIG, TASK_PRESETS, resolve_task_config

    exp = load_experiment("ablation_static_density")
    proto = protocol(exp.protocol)
    street: dict[float, float] = {}
    for run in exp.runs:
        cfg = deep_merge(proto.env_config, run.env)
        scene = resolve_task_config(DEFAULT_CONFIG, {k: cfg[k] for k in ("preset", "scene")}, TASK_PRESETS)["scene"]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # no catalog: default-size boxes, the same counts
            scenes = [generate_scene(scene, seed) for seed in range(3)]
        counts = [s["stats"]["objects"] - s["stats"]["buildings"] for s in scenes]  # street objects: facades aside
        street[float(run.setting)] = sum(counts) / len(counts)
    densities = sorted(street)
    assert [street[d] for d in densities] == sorted(street.values()), street  # more objects at each higher setting
    assert street[densities[0]] < 0.1 * street[densities[-1]], street
