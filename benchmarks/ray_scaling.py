"""Beyond one machine: throughput with 1 vs 2 Ray workers, RLlib vs SB3, and a simulated 8-node run.

Usage: python benchmarks/ray_scaling.py --budget {smoke,full} [--out DIR] [--parts scenes,eval,ppo,nodes]

Prints and writes (ray_scaling.json, ray_scaling.csv under --out, default benchmarks/results/ray_scaling):
- scenes/s of `curbside scenes dataset` (the metaurban12k preset, 3 blocks) on a local Ray cluster of 1 and of 2
  CPUs, timed after the workers have started and imported the simulator (the cluster start is reported apart), in
  `rounds` back-to-back pairs (1 worker, then 2; 3 pairs with the full budget), the figure the median pair's ratio;
- eval episodes/s of `curbside sim eval` (PointNav, the expert) the same way (Ray workers keep the env they built
  in the warm-up; the local run builds its env inside the timed call, ~0.1 s);
- RLlib PPO env steps/s with 2 env runners against SB3 PPO in one process with as many envs (2; and 8 with the
  full budget), on the same task and hyperparameters (each trainer's own logs/progress.csv `time/fps`: env steps over the time since
  training started, updates included, env and worker start-up excluded);
- a simulated 8-node cluster (ray.cluster_utils.Cluster, 8 one-CPU raylets on this machine): scenes and eval
  metrics aggregated from the nodes are compared byte for byte with a local run.
Every Ray output is checked byte-identical to the local (in-process) run of the same seeds. The 1-minute load
average is recorded before each timed part: other work on the machine slows the figures.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

BUDGETS = {
    "smoke": {
        "scenes": 6,
        "episodes": 6,
        "ppo_steps": 2048,
        "ppo_envs": (2,),
        "node_scenes": 8,
        "node_episodes": 8,
        "rounds": 1,
    },
    "full": {
        "scenes": 300,
        "episodes": 80,
        "ppo_steps": 16384,
        "ppo_envs": (2, 8),
        "node_scenes": 24,
        "node_episodes": 24,
        "rounds": 3,
    },
}
SCENE_BASE = {"blocks": 3, "preset": "metaurban12k"}  # `curbside scenes dataset`'s defaults
EVAL_ENV = "curbside/PointNav-v0"
PPO_TASK_CONFIG: dict[str, Any] = {}  # the PointNav defaults, as `curbside train run` uses them
NODES = 8


def load1() -> float:
    """The 1-minute load average now."""
    return round(os.getloadavg()[0], 2)


def tree_digest(folder: Path) -> str:
    """sha256 over every file's relative path and bytes."""
    h = hashlib.sha256()
    for f in sorted(folder.rglob("*")):
        if f.is_file():
            h.update(str(f.relative_to(folder)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def _ray_local(cpus: int) -> float:
    """Start a local Ray cluster of `cpus` CPUs; seconds it took."""
    from kernel.executors import connect_ray

    t0 = time.perf_counter()
    connect_ray(cpus)  # as `--executor ray --workers N` starts one: workers at this process's priority
    return time.perf_counter() - t0


def _pair_up(out: dict[str, Any], rate: str) -> None:
    """Summarise paired rounds: each round's 2-vs-1 ratio, their median (the figure), and the median round's
    runs as `ray_1` / `ray_2` (the machine's speed drifts between runs minutes apart: pairs taken back to back
    compare like with like)."""
    ones, twos = out["rounds_ray_1"], out["rounds_ray_2"]
    ratios = [b[rate] / a[rate] for a, b in zip(ones, twos)]
    mid = sorted(range(len(ratios)), key=ratios.__getitem__)[len(ratios) // 2]
    out["ray_1"], out["ray_2"] = ones[mid], twos[mid]
    out["round_speedups"] = ratios
    out["speedup_2_vs_1"] = ratios[mid]


def scenes_part(n: int, work: Path, rounds: int = 1) -> dict[str, Any]:
    """Scenes/s in-process and on Ray with 1 and 2 workers (`rounds` pairs); whether all outputs are the same
    bytes."""
    import ray

    from sim.scene.dataset import build_dataset

    out: dict[str, Any] = {"count": n, "config": SCENE_BASE}
    build_dataset("finetune", 2, work / "warm0", base=SCENE_BASE, executor="local")  # imports, as the workers' warm-up
    t0, load = time.perf_counter(), load1()
    build_dataset("train", n, work / "scenes_local", base=SCENE_BASE, executor="local")
    out["local"] = {"seconds": time.perf_counter() - t0, "scenes_per_s": n / (time.perf_counter() - t0), "load1": load}
    digest = tree_digest(work / "scenes_local")
    for r in range(rounds):  # 1 then 2 workers, back to back, `rounds` times: the ratio of each pair
        for w in (1, 2):
            start = _ray_local(w)
            try:
                # Warm-up on other seeds (the finetune split): every worker starts and imports the generator (8
                # scenes a worker: with 2 a worker, Ray could hand both of the first two to one worker).
                build_dataset("finetune", 8 * w, work / f"warm{w}_{r}", base=SCENE_BASE, executor="ray", workers=w)
                load, t0 = load1(), time.perf_counter()
                build_dataset("train", n, work / f"scenes_ray{w}_{r}", base=SCENE_BASE, executor="ray", workers=w)
                dt = time.perf_counter() - t0
            finally:
                ray.shutdown()
            out.setdefault(f"rounds_ray_{w}", []).append(
                {
                    "seconds": dt,
                    "scenes_per_s": n / dt,
                    "cluster_start_s": start,
                    "load1": load,
                    "same_bytes_as_local": tree_digest(work / f"scenes_ray{w}_{r}") == digest,
                }
            )
    _pair_up(out, "scenes_per_s")
    return out


def eval_part(n: int, rounds: int = 1) -> dict[str, Any]:
    """Eval episodes/s in-process and on Ray with 1 and 2 workers (`rounds` pairs); whether the summaries are the
    same bytes."""
    import ray

    from sim.eval import evaluate

    out: dict[str, Any] = {"episodes": n, "env": EVAL_ENV, "policy": "expert"}
    evaluate(EVAL_ENV, "expert", 2, {}, seed=10_000)  # imports, as the workers' warm-up (the env is built in both)
    load, t0 = load1(), time.perf_counter()
    local = json.dumps(evaluate(EVAL_ENV, "expert", n, {}, seed=0), sort_keys=True)
    out["local"] = {
        "seconds": time.perf_counter() - t0,
        "episodes_per_s": n / (time.perf_counter() - t0),
        "load1": load,
    }
    for _ in range(rounds):  # 1 then 2 workers, back to back, `rounds` times (see _pair_up)
        for w in (1, 2):
            start = _ray_local(w)
            try:
                evaluate(EVAL_ENV, "expert", 2 * w, {}, seed=10_000, executor="ray", workers=w)  # workers build envs
                load, t0 = load1(), time.perf_counter()
                summary = evaluate(EVAL_ENV, "expert", n, {}, seed=0, executor="ray", workers=w)
                dt = time.perf_counter() - t0
            finally:
                ray.shutdown()
            out.setdefault(f"rounds_ray_{w}", []).append(
                {
                    "seconds": dt,
                    "episodes_per_s": n / dt,
                    "cluster_start_s": start,
                    "load1": load,
                    "same_bytes_as_local": json.dumps(summary, sort_keys=True) == local,
                }
            )
    _pair_up(out, "episodes_per_s")
    return out


def _fps(run: Path) -> tuple[float, int]:
    """(time/fps, time/total_timesteps) of the last row of a run's logs/progress.csv."""
    with open(run / "logs" / "progress.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if r.get("time/fps")]
    return float(rows[-1]["time/fps"]), int(float(rows[-1]["time/total_timesteps"]))


def ppo_part(steps: int, envs: tuple[int, ...], work: Path) -> dict[str, Any]:
    """RLlib PPO with 2 env runners vs SB3 PPO in one process, with the same number of envs: env steps/s while
    training (2 envs: one per runner; 8 envs: four per runner, sampled as one vector in each runner)."""
    from curbside.train.run import train

    out: dict[str, Any] = {"task": "PointNav", "steps": steps, "hparams": "curbside.train.protocols (curbside)"}
    for n in envs:
        load = load1()
        train(
            "ppo",
            "PointNav",
            work / f"sb3_{n}",
            steps=steps,
            env_config=PPO_TASK_CONFIG,
            n_envs=n,
            num_scenes=8,
            progress=False,
            subprocess=False,
        )
        fps, total = _fps(work / f"sb3_{n}")
        out[f"sb3_one_process_{n}_envs"] = {"envs": n, "env_steps_per_s": fps, "env_steps": total, "load1": load}
        load = load1()
        train(
            "ppo",
            "PointNav",
            work / f"rllib_{n}",
            steps=steps,
            env_config=PPO_TASK_CONFIG,
            n_envs=n,
            num_scenes=8,
            progress=False,
            executor="ray",
            num_env_runners=2,
        )
        fps, total = _fps(work / f"rllib_{n}")
        out[f"rllib_2_env_runners_{n}_envs"] = {"envs": n, "env_steps_per_s": fps, "env_steps": total, "load1": load}
        out[f"ratio_rllib_vs_sb3_{n}_envs"] = fps / out[f"sb3_one_process_{n}_envs"]["env_steps_per_s"]
    return out


def nodes_part(n_scenes: int, n_episodes: int, work: Path) -> dict[str, Any]:
    """Scenes and eval on a simulated 8-node cluster against a local run: same bytes, and which nodes ran what."""
    import ray
    from ray.cluster_utils import Cluster

    from sim.eval import evaluate
    from sim.scene.dataset import build_dataset

    base = {"blocks": 1}
    build_dataset("test", n_scenes, work / "nodes_local", base=base, executor="local")
    local_eval = json.dumps(evaluate("curbside/SocialNav-v0", "expert", n_episodes, {}, seed=0), sort_keys=True)
    os.environ.setdefault("RAY_AUTH_MODE", "disabled")
    t0 = time.perf_counter()
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    for _ in range(NODES - 1):
        cluster.add_node(num_cpus=1)
    cluster.wait_for_nodes()
    ray.init(address=cluster.address, log_to_driver=False)
    start = time.perf_counter() - t0
    try:
        scene_nodes: dict[str, int] = {}
        build_dataset("test", n_scenes, work / "nodes_ray", base=base, executor="ray", nodes=scene_nodes)
        eval_nodes: dict[str, int] = {}
        sharded = json.dumps(
            evaluate("curbside/SocialNav-v0", "expert", n_episodes, {}, seed=0, executor="ray", nodes=eval_nodes),
            sort_keys=True,
        )
        alive = sum(1 for n in ray.nodes() if n["Alive"])
    finally:
        ray.shutdown()
        cluster.shutdown()
    return {
        "nodes": NODES,
        "alive_nodes": alive,
        "cluster_start_s": start,
        "scenes": n_scenes,
        "episodes": n_episodes,
        "scene_nodes_used": len(scene_nodes),
        "eval_nodes_used": len(eval_nodes),
        "scenes_per_node": sorted(scene_nodes.values(), reverse=True),
        "episodes_per_node": sorted(eval_nodes.values(), reverse=True),
        "scenes_same_bytes": tree_digest(work / "nodes_ray") == tree_digest(work / "nodes_local"),
        "eval_same_bytes": sharded == local_eval,
    }


PARTS = ("scenes", "eval", "ppo", "nodes")


def _ratios(part: dict[str, Any]) -> str:
    """The rounds' 2-vs-1 ratios as text."""
    return ", ".join(f"{r:.2f}x" for r in part["round_speedups"])


def main(budget: str, out: Path, parts: tuple[str, ...] = PARTS) -> dict[str, Any]:
    """Run the chosen parts; print and write the figures (ray_scaling.json/.csv, or ray_scaling_<parts>.* for some)."""
    b = BUDGETS[budget]
    result: dict[str, Any] = {
        "budget": budget,
        "cpus": os.cpu_count(),
        "load1_start": load1(),
        "date": time.strftime("%Y-%m-%d %H:%M"),
    }
    work = Path(tempfile.mkdtemp(prefix="ray_scaling_"))
    try:
        if "scenes" in parts:
            result["scenes"] = scenes_part(b["scenes"], work, b["rounds"])
            print(
                f"scenes/s: local {result['scenes']['local']['scenes_per_s']:.2f}, Ray 1 worker "
                f"{result['scenes']['ray_1']['scenes_per_s']:.2f}, 2 workers "
                f"{result['scenes']['ray_2']['scenes_per_s']:.2f} ({result['scenes']['speedup_2_vs_1']:.2f}x, the median of "
                f"{_ratios(result['scenes'])})",
                flush=True,
            )
        if "eval" in parts:
            result["eval"] = eval_part(b["episodes"], b["rounds"])
            print(
                f"eval episodes/s: local {result['eval']['local']['episodes_per_s']:.2f}, Ray 1 worker "
                f"{result['eval']['ray_1']['episodes_per_s']:.2f}, 2 workers "
                f"{result['eval']['ray_2']['episodes_per_s']:.2f} ({result['eval']['speedup_2_vs_1']:.2f}x, the median of "
                f"{_ratios(result['eval'])})",
                flush=True,
            )
        if "ppo" in parts:
            result["ppo"] = ppo_part(b["ppo_steps"], b["ppo_envs"], work)
            for n in b["ppo_envs"]:
                print(
                    f"PPO env steps/s, {n} envs: RLlib 2 env runners "
                    f"{result['ppo'][f'rllib_2_env_runners_{n}_envs']['env_steps_per_s']:.0f}, SB3 one process "
                    f"{result['ppo'][f'sb3_one_process_{n}_envs']['env_steps_per_s']:.0f} "
                    f"({result['ppo'][f'ratio_rllib_vs_sb3_{n}_envs']:.2f}x)",
                    flush=True,
                )
        if "nodes" in parts:
            result["nodes8"] = n8 = nodes_part(b["node_scenes"], b["node_episodes"], work)
            print(
                f"8-node cluster: scenes on {n8['scene_nodes_used']} nodes, episodes on {n8['eval_nodes_used']}; "
                f"scenes same bytes {n8['scenes_same_bytes']}, eval same bytes {n8['eval_same_bytes']}",
                flush=True,
            )
    finally:
        shutil.rmtree(work, ignore_errors=True)
    result["load1_end"] = load1()
    out.mkdir(parents=True, exist_ok=True)
    stem = "ray_scaling" if tuple(parts) == PARTS else "ray_scaling_" + "_".join(parts)
    (out / f"{stem}.json").write_text(json.dumps(result, indent=2, sort_keys=True) + "\n")
    rows = []
    if "scenes" in result:
        rows += [
            ("scenes/s", k, result["scenes"][k]["scenes_per_s"], result["scenes"][k]["load1"])
            for k in ("local", "ray_1", "ray_2")
        ]
    if "eval" in result:
        rows += [
            ("eval episodes/s", k, result["eval"][k]["episodes_per_s"], result["eval"][k]["load1"])
            for k in ("local", "ray_1", "ray_2")
        ]
    if "ppo" in result:
        rows += [
            ("PPO env steps/s", k, v["env_steps_per_s"], v["load1"])
            for k, v in result["ppo"].items()
            if isinstance(v, dict)
        ]
    with open(out / f"{stem}.csv", "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["figure", "run", "value", "load1"])
        w.writerows([(a, b_, f"{v:.3f}", ld) for a, b_, v, ld in rows])
    print(f"wrote {out / (stem + '.json')} and {out / (stem + '.csv')}")
    return result


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget", choices=sorted(BUDGETS), default="smoke")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "ray_scaling")
    parser.add_argument("--parts", default=",".join(PARTS), help="comma-separated subset of " + ", ".join(PARTS))
    args = parser.parse_args()
    chosen = tuple(p for p in PARTS if p in args.parts.split(","))
    if not chosen or set(args.parts.split(",")) - set(PARTS):
        parser.error(f"--parts takes a comma-separated subset of {', '.join(PARTS)}")
    main(args.budget, args.out, chosen)
