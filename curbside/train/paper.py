"""MetaUrban's Table 1 (Wu et al., ICLR 2025): the figures curbside's baselines are printed beside.

Keys: (task, split, algo). PointNav reports SR, SPL, Cost; SocialNav SR, SNS, Cost. Only figures quoted from the
paper are here; a missing cell means the paper's value was not transcribed, never an estimate.
"""

from __future__ import annotations

PAPER_TABLE1: dict[tuple[str, str, str], dict[str, float]] = {
    ("PointNav", "test", "ppo"): {"sr": 0.66, "spl": 0.64, "cost": 0.51},
    ("PointNav", "unseen", "ppo"): {"sr": 0.49, "spl": 0.45, "cost": 0.78},
    ("SocialNav", "test", "ppo"): {"sr": 0.34, "sns": 0.64},
}
