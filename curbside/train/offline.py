"""Offline RL on d3rlpy (IQL, TD3+BC) from a Minari demonstration set: gradient steps, not env steps."""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from curbside.train.demos import Transitions
from curbside.train.progress import progress_bar


def _quiet_d3rlpy() -> None:
    import structlog
    # d3rlpy logs every epoch through structlog at INFO; the CLI reports progress itself.
    structlog.configure(wrapper_class=structlog.make_filtering_bound_logger(logging.WARNING))


def mdp_dataset(tr: Transitions) -> Any:
    """A d3rlpy MDPDataset of the transitions (episode ends from terminals and timeouts)."""
    import d3rlpy

    timeouts = tr.timeouts.astype(np.float32)
    # d3rlpy splits episodes on terminal or timeout flags; a dataset must end on one.
    if not (tr.terminals[-1] or timeouts[-1]):
        timeouts[-1] = 1.0
    return d3rlpy.dataset.MDPDataset(tr.obs, tr.actions, tr.rewards, tr.terminals.astype(np.float32), timeouts=timeouts,
                                     action_space=d3rlpy.ActionSpace.CONTINUOUS)


def offline_config(algo: str, hparams: Mapping[str, Any]) -> Any:
    """d3rlpy's config of `algo` (iql, td3bc) with a protocol's hyper-parameters (curbside.train.protocols)."""
    import d3rlpy

    h = dict(hparams)
    lr = float(h.get("learning_rate", 3e-4))
    common = {"batch_size": int(h.get("batch_size", 256)), "gamma": float(h.get("gamma", 0.99)),
              "tau": float(h.get("tau", 5e-3)), "actor_learning_rate": lr, "critic_learning_rate": lr}
    if algo == "iql":
        return d3rlpy.algos.IQLConfig(**common, expectile=float(h.get("expectile", 0.7)),
                                      weight_temp=float(h.get("beta", 3.0)))
    return d3rlpy.algos.TD3PlusBCConfig(**common, alpha=float(h.get("alpha", 2.5)),
                                        update_actor_interval=int(h.get("actor_delay", 2)))


def train_offline(algo: str, demos: Transitions, out: Path, *, steps: int, seed: int = 0,
                  hparams: Mapping[str, Any] | None = None, progress: bool = True) -> Path:
    """Train IQL or TD3+BC for `steps` gradient steps; write `policy.d3` (config + weights) and a CSV log."""
    import d3rlpy
    import torch

    _quiet_d3rlpy()
    torch.set_num_threads(2)
    d3rlpy.seed(seed)
    learner = offline_config(algo, hparams or {}).create(device="cpu")
    ds = mdp_dataset(demos)
    # d3rlpy runs steps // per_epoch epochs: an epoch length that divides `steps` trains exactly `steps`.
    per_epoch = next(d for d in range(min(1000, steps), 0, -1) if steps % d == 0)
    log = []
    with progress_bar(f"{algo} gradient steps", steps, progress) as update:
        for epoch, metrics in learner.fitter(ds, n_steps=steps, n_steps_per_epoch=per_epoch, show_progress=False,
                                              logger_adapter=d3rlpy.logging.NoopAdapterFactory()):
            log.append({"epoch": epoch, "gradient_steps": epoch * per_epoch, **{k: float(v) for k, v in metrics.items()}})
            update(epoch * per_epoch)
    out.mkdir(parents=True, exist_ok=True)
    (out / "train_log.json").write_text(json.dumps(log, indent=1))
    path = out / "policy.d3"
    learner.save(str(path))
    return path
