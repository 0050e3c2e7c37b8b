"""Default settings of a training run and of a demonstration collection, declared once.

curbside.train.run.train and curbside.train.demos.collect_demos take them as keyword defaults, and the
`curbside train` / `curbside demos` options show the same values. Plain constants with no imports, so the CLI
reads them without loading the trainers.
"""

from __future__ import annotations

# curbside.train.run.train (`curbside train run` / `train ppo`); None: the protocol's.
RUN_N_ENVS: int | None = None
RUN_NUM_SCENES: int | None = None
RUN_SEED = 0
RUN_EVAL_EVERY = 0  # env steps between learning-curve evaluations; 0: never

# curbside.train.demos.collect_demos (`curbside demos collect`).
DEMOS_STEPS = 30_000
DEMOS_NOISE = 0.7  # std of the Gaussian noise on the expert's actions
DEMOS_RANDOM_PROB = 0.0
DEMOS_NUM_SCENES = 64
DEMOS_SEED = 0
