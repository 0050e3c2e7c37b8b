"""Run one SocialNav expert episode and write its metrics (JSON) and a top-down GIF with agents and trails.

Usage: python -m sim.agents.demo --out outputs/socialnav [--seed 0] [--agents 24]
"""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path

from numpy.typing import ArrayLike


def run_episode(out: Path, seed: int = 0, n_agents: int = 24, size: int = 320) -> dict[str, float]:
    """Drive the built-in expert through one SocialNav episode; write `<out>.gif`, `<out>.png`, `<out>.json`."""
    import gymnasium as gym
    import imageio.v2 as imageio

    from sim.agents.kinds import DEFAULT_MIX
    from sim.envs import register_envs
    from sim.expert import PurePursuitExpert
    from sim.rollout import rollout

    register_envs()
    counts = {k: max(1, int(round(v * n_agents))) for k, v in DEFAULT_MIX.items()}
    cfg = {"agents": {"counts": counts}, "render": {"camera": "map", "width": size, "height": size}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = gym.make("curbside/SocialNav-v0", config=cfg, render_mode="rgb_array")
    expert = PurePursuitExpert()  # the demo's machine is the default delivery robot
    frames: list[ArrayLike] = []  # rendered frames, for imageio only
    try:
        metrics = rollout(
            env,
            lambda e, obs: expert.act(e),
            seed,
            on_reset=lambda e: frames.append(e.render()),
            on_step=lambda e, done: frames.append(e.render()),
        )
    finally:
        env.close()
    out.parent.mkdir(parents=True, exist_ok=True)
    imageio.mimsave(out.with_suffix(".gif"), frames[::2], duration=200, loop=0)
    imageio.imwrite(out.with_suffix(".png"), frames[len(frames) // 2])
    metrics = {k: float(v) for k, v in metrics.items()}
    metrics["agents"] = float(sum(counts.values()))
    out.with_suffix(".json").write_text(json.dumps(metrics, indent=2, sort_keys=True))
    return metrics


def main() -> None:
    """Command-line entry: run the episode and print the headline metrics."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, default=Path("outputs/socialnav"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--agents", type=int, default=24)
    args = ap.parse_args()
    m = run_episode(args.out, args.seed, args.agents)
    print(
        f"SocialNav expert episode: success {m['success']:.0f}  SNS {m['sns']:.3f}  PSC {m['psc']:.3f}  "
        f"STL {m['stl']:.3f}  cost {m['cost']:.0f}  -> {args.out}.gif / .json"
    )


if __name__ == "__main__":
    main()
