"""The `paper` protocol's fidelity check: MetaUrban's world as curbside runs it, measured where a reader compares it
with the paper. Writes benchmarks/results/fidelity/summary.json (and one JSON file a part beside it).

Usage: python benchmarks/fidelity.py [--episodes 200] [--transfer-episodes 400] [--ppo-steps 1000000] [--seeds 0 1 2]
       [--workers 2] [--out benchmarks/results/fidelity] [--run-dir outputs/fidelity/ppo_1m] [--fresh]

Parts, each skipped when its file exists (`--fresh` measures it again):
1. `expert.json`: the pure-pursuit expert (`PurePursuitExpert.for_machine`) on `--episodes` test episodes (seeds
   0..N-1, the protocol's evaluation scenes and episode ends) on the PyBullet env: its SR and cost an episode.
2. `ppo_1m.json`: PPO trained `--ppo-steps` env steps under `paper` on the batched backend, once per `--seeds` seed
   (`curbside train run --protocol paper --algo ppo --backend batched`, into `<run-dir>_s<seed>`; with `--resume` a
   stopped run goes on), each evaluated as the protocol evaluates (PyBullet env, `--episodes` test episodes, sampled
   actions): the mean over seeds, and each seed's.
3. `transfer.json`: the first seed's policy on `--transfer-episodes` test episodes on both backends, the same seeds
   (benchmarks/transfer_gap.py with the protocol's episode ends and actions): PyBullet's SR minus the batched env's.

summary.json: `horizon` (the protocol's, as the env resolves it), `expert_test_sr`, `expert_test_cost`,
`ppo_1m_test_sr`, `ppo_1m_test_cost` (means over the seeds; `ppo_1m_test_sr_seeds` each seed's), `transfer_gap_sr`,
with the commands and seconds of each part.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

PROTOCOL = "paper"
TASK = "PointNav"


def _write(path: Path, data: dict[str, Any]) -> None:
    """Write JSON beside the old file and swap, so a stopped run never leaves half a file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
    tmp.replace(path)


def _eval_config() -> tuple[dict[str, Any], int]:
    """The protocol's evaluation env config (its env config and evaluation ends) and its evaluation scenes."""
    from curbside.train.protocols import deep_merge, protocol

    proto = protocol(PROTOCOL)
    return deep_merge(proto.env_for(TASK), proto.eval_env), proto.eval_scenes


def expert_part(episodes: int, workers: int) -> dict[str, Any]:
    """The expert on the protocol's test episodes (PyBullet env)."""
    from curbside.train.envs import split_config
    from sim.eval import evaluate

    cfg, scenes = _eval_config()
    cfg = split_config(cfg, "test", scenes)
    cfg.update(scene_cache=1, scene_steps=0)  # as every evaluation: each episode's scene follows from its seed
    t0 = time.perf_counter()
    summary = evaluate(
        "curbside/PointNav-v0",
        "expert",
        episodes,
        cfg,
        seed=0,
        executor="process" if workers > 1 else "local",
        workers=workers,
        progress=True,
    )
    return {
        "episodes": episodes,
        "sr": float(summary["sr"]),
        "spl": float(summary["spl"]),
        "cost": float(summary["cost"]),
        "route_completion": float(summary.get("route_completion", float("nan"))),
        "seconds": round(time.perf_counter() - t0, 1),
    }


def ppo_part(run_dir: Path, steps: int, episodes: int, workers: int, seeds: list[int]) -> dict[str, Any]:
    """`ppo_seed` for every seed: their means and each seed's part."""
    import numpy as np

    runs = {str(seed): ppo_seed(seeded(run_dir, seed), steps, episodes, workers, seed) for seed in seeds}
    return {
        "steps": steps,
        "episodes": episodes,
        "seeds": seeds,
        "sr": float(np.mean([r["sr"] for r in runs.values()])),
        "spl": float(np.mean([r["spl"] for r in runs.values()])),
        "cost": float(np.mean([r["cost"] for r in runs.values()])),
        "runs": runs,
    }


def seeded(run_dir: Path, seed: int) -> Path:
    """The run folder of one seed."""
    return run_dir.with_name(f"{run_dir.name}_s{seed}")


def ppo_seed(run_dir: Path, steps: int, episodes: int, workers: int, seed: int) -> dict[str, Any]:
    """Train (or finish training) PPO under the protocol with `seed`, then evaluate it as the protocol does."""
    from curbside.train.evaluate import evaluate_run
    from curbside.train.protocols import deep_merge, protocol

    train = [
        "curbside",
        "train",
        "run",
        "--protocol",
        PROTOCOL,
        "--algo",
        "ppo",
        "--task",
        TASK,
        "--backend",
        "batched",
        "--steps",
        str(steps),
        "--seed",
        str(seed),
        "--out",
        str(run_dir),
    ]
    t0 = time.perf_counter()
    if not (run_dir / "policy.zip").is_file():
        exe = Path(sys.executable).with_name("curbside")
        resume = ["--resume"] if (run_dir / "run.json").is_file() else []  # a stopped run goes on
        subprocess.run([str(exe), *train[1:], *resume], check=True)
    t1 = time.perf_counter()
    run = json.loads((run_dir / "run.json").read_text())
    proto = protocol(PROTOCOL)
    summary = evaluate_run(
        run_dir,
        TASK,
        deep_merge(run["env_config"], proto.eval_env),
        split="test",
        episodes=episodes,
        num_scenes=proto.eval_scenes,
        workers=workers,
        actions=proto.eval_actions,
    )
    return {
        "command": " ".join(shlex.quote(a) for a in train),
        "steps": steps,
        "episodes": episodes,
        "actions": proto.eval_actions,
        "sr": float(summary["sr"]),
        "spl": float(summary["spl"]),
        "cost": float(summary["cost"]),
        "seconds": {"train": _train_seconds(run_dir, t1 - t0), "evaluate": round(time.perf_counter() - t1, 1)},
    }


def _train_seconds(run_dir: Path, here: float) -> float:
    """Seconds the run trained: its progress log's clock (a run trained before this script ran), else `here`."""
    import csv

    log = run_dir / "logs" / "progress.csv"
    rows = list(csv.DictReader(log.open())) if log.is_file() else []
    elapsed = [float(r["time/time_elapsed"]) for r in rows if r.get("time/time_elapsed")]
    return round(max(elapsed), 1) if elapsed else round(here, 1)


def transfer_part(run_dir: Path, episodes: int, workers: int, out: Path) -> dict[str, Any]:
    """benchmarks/transfer_gap.py on the PPO run: the same episodes on both backends."""
    shown = os.path.relpath(out) if not out.is_absolute() or out.is_relative_to(Path.cwd()) else str(out)
    cmd = [
        sys.executable,
        str(ROOT / "benchmarks" / "transfer_gap.py"),
        str(run_dir),
        "--split",
        "test",
        "--episodes",
        str(episodes),
        "--actions",
        "sampled",
        "--episode-ends",
        "protocol",
        "--workers",
        str(workers),
        "--out",
        shown,
    ]
    subprocess.run(cmd, check=True)
    return json.loads(out.read_text())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=200)
    ap.add_argument("--transfer-episodes", type=int, default=400)
    ap.add_argument("--ppo-steps", type=int, default=1_000_000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "fidelity")
    ap.add_argument(
        "--run-dir", type=Path, default=Path("outputs/fidelity/ppo_1m"), help="seed s trains in <run-dir>_s<s>"
    )
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="PPO seeds (the transfer part: the first)")
    ap.add_argument("--fresh", action="store_true", help="measure every part again")
    ap.add_argument("--only", choices=("expert", "ppo_1m", "transfer"), help="measure this part alone (no summary)")
    args = ap.parse_args()
    from sim.tasks.pointnav import DEFAULT_CONFIG, resolve_task_config

    out: Path = args.out
    parts: dict[str, dict[str, Any]] = {}
    for name, measure in (
        ("expert", lambda: expert_part(args.episodes, args.workers)),
        ("ppo_1m", lambda: ppo_part(args.run_dir, args.ppo_steps, args.episodes, args.workers, args.seeds)),
    ):
        if args.only not in (None, name):
            continue
        path = out / f"{name}.json"
        if args.fresh or not path.is_file():
            _write(path, measure())
        parts[name] = json.loads(path.read_text())
        print(name, json.dumps(parts[name]))
    if args.only not in (None, "transfer"):
        return
    path = out / "transfer.json"
    if args.fresh or not path.is_file():
        transfer_part(seeded(args.run_dir, args.seeds[0]), args.transfer_episodes, args.workers, path)
    if args.only is not None:
        return
    parts["transfer"] = json.loads(path.read_text())
    cfg = resolve_task_config(DEFAULT_CONFIG, _eval_config()[0])
    summary = {
        "command": "python benchmarks/" + " ".join(shlex.quote(a) for a in [Path(__file__).name, *sys.argv[1:]]),
        "protocol": PROTOCOL,
        "task": TASK,
        "horizon": int(cfg["horizon"]) if cfg["horizon_min_speed"] is None else None,
        "expert_test_sr": parts["expert"]["sr"],
        "expert_test_cost": parts["expert"]["cost"],
        "expert_episodes": parts["expert"]["episodes"],
        "ppo_1m_test_sr": parts["ppo_1m"]["sr"],
        "ppo_1m_test_cost": parts["ppo_1m"]["cost"],
        "ppo_1m_seeds": parts["ppo_1m"]["seeds"],
        "ppo_1m_test_sr_seeds": [parts["ppo_1m"]["runs"][str(s)]["sr"] for s in parts["ppo_1m"]["seeds"]],
        "ppo_1m_episodes": parts["ppo_1m"]["episodes"],
        "transfer_gap_sr": parts["transfer"]["pybullet_minus_batched"]["sr"],
        "transfer_episodes": parts["transfer"]["episodes"],
    }
    _write(out / "summary.json", summary)
    print(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
