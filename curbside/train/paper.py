"""Every number the MetaUrban paper (Wu et al., ICLR 2025) publishes for its experiments, as curbside prints them beside
its own. Sources are named per table; a cell the paper does not publish is absent, never estimated.

Rates are fractions (the paper's 66 % is 0.66). Table 1 reports SR / SPL / Cost for PointNav and SR / SNS / Cost for
SocialNav; Table 2 SR / SPL / Cost on the S and X blocks; Table 5 SR (and SPL or Cost).
"""

from __future__ import annotations

TABLE1_SOURCE = "MetaUrban, ICLR 2025, Table 1 (PointNav and SocialNav benchmarks)"
METHODS = ("ppo", "ppo_lag", "ppo_et", "iql", "td3bc", "bc", "gail")
METHOD_NAMES = {
    "ppo": "PPO",
    "ppo_lag": "PPO-Lag",
    "ppo_et": "PPO-ET",
    "iql": "IQL",
    "td3bc": "TD3+BC",
    "bc": "BC",
    "gail": "GAIL",
}

# (method) -> (PointNav test, PointNav unseen, SocialNav test, SocialNav unseen), each (SR, SPL or SNS, Cost).
_TABLE1_ROWS: dict[str, tuple[tuple[float, float, float], ...]] = {
    "ppo": ((0.66, 0.64, 0.51), (0.49, 0.45, 0.78), (0.34, 0.64, 0.66), (0.24, 0.57, 0.51)),
    "ppo_lag": ((0.60, 0.58, 0.41), (0.60, 0.57, 0.53), (0.17, 0.51, 0.33), (0.08, 0.47, 0.50)),
    "ppo_et": ((0.57, 0.53, 0.47), (0.53, 0.49, 0.65), (0.05, 0.52, 0.26), (0.02, 0.50, 0.62)),
    "iql": ((0.36, 0.33, 0.49), (0.30, 0.27, 0.63), (0.36, 0.67, 0.39), (0.27, 0.62, 3.05)),
    "td3bc": ((0.29, 0.28, 0.77), (0.20, 0.20, 1.16), (0.26, 0.61, 0.62), (0.32, 0.64, 1.53)),
    "bc": ((0.36, 0.28, 0.83), (0.32, 0.26, 1.15), (0.28, 0.56, 1.23), (0.18, 0.54, 0.58)),
    "gail": ((0.47, 0.36, 1.05), (0.40, 0.32, 1.46), (0.34, 0.63, 0.71), (0.28, 0.61, 0.67)),
}
_COLUMNS = (("PointNav", "test"), ("PointNav", "unseen"), ("SocialNav", "test"), ("SocialNav", "unseen"))


def _table1() -> dict[tuple[str, str, str], dict[str, float]]:
    table: dict[tuple[str, str, str], dict[str, float]] = {}
    for method, cells in _TABLE1_ROWS.items():
        for (task, split), (sr, second, cost) in zip(_COLUMNS, cells):
            table[(task, split, method)] = {"sr": sr, "spl" if task == "PointNav" else "sns": second, "cost": cost}
    return table


# Keys (task, split, method): 28 cells of 3 numbers, the paper's 84.
PAPER_TABLE1: dict[tuple[str, str, str], dict[str, float]] = _table1()

SEED_ROBUSTNESS_SOURCE = "MetaUrban, ICLR 2025, appendix (robustness across seeds)"
# PPO PointNav SR, mean and std over seeds.
PAPER_SEED_ROBUSTNESS: dict[str, dict[str, float]] = {
    "test": {"sr": 0.695, "sr_std": 0.014},
    "unseen": {"sr": 0.638, "sr_std": 0.060},
}

TABLE2_SOURCE = "MetaUrban, ICLR 2025, Table 2 (policy learning across machines; PPO, PointNav setting)"
# machine -> block (S: straight, mainly static obstacles; X: intersection, dense pedestrians) -> SR, SPL, Cost.
PAPER_TABLE2: dict[str, dict[str, dict[str, float]]] = {
    "delivery_bot": {"S": {"sr": 0.47, "spl": 0.46, "cost": 0.32}, "X": {"sr": 0.41, "spl": 0.38, "cost": 1.50}},
    "delivery_bot_mod1": {"S": {"sr": 0.62, "spl": 0.61, "cost": 0.28}, "X": {"sr": 0.56, "spl": 0.53, "cost": 1.64}},
    "delivery_bot_mod2": {"S": {"sr": 0.17, "spl": 0.15, "cost": 0.35}, "X": {"sr": 0.22, "spl": 0.20, "cost": 1.21}},
    "wheelchair": {"S": {"sr": 0.13, "spl": 0.11, "cost": 0.30}, "X": {"sr": 0.16, "spl": 0.14, "cost": 1.10}},
    "mobility_scooter": {"S": {"sr": 0.36, "spl": 0.33, "cost": 0.34}, "X": {"sr": 0.31, "spl": 0.28, "cost": 1.43}},
}

TABLE5_SOURCE = "MetaUrban, ICLR 2025, Table 5 (unique challenges; PPO, tested on MetaUrban-test)"
# Long horizon: models trained on a mean route of 10 m (setting 1) and 410 m (setting 2).
PAPER_TABLE5_HORIZON: dict[str, dict[str, float]] = {
    "10 m": {"sr": 0.10, "spl": 0.08},
    "410 m": {"sr": 0.41, "spl": 0.38},
}
# Dense pedestrians (SocialNav): 1 trains with 10 pedestrians per 100 m, 2 with 5, 3 with 10 at intersections only,
# 4 tests the setting-1 model at 30 per 100 m.
PAPER_TABLE5_PEDESTRIANS: dict[str, dict[str, float]] = {
    "1": {"sr": 0.24, "cost": 0.51},
    "2": {"sr": 0.16, "cost": 0.75},
    "3": {"sr": 0.10, "cost": 0.74},
    "4": {"sr": 0.08, "cost": 0.68},
}

ABLATION_SOURCE = "MetaUrban, ICLR 2025, ablation figure (PPO, PointNav unless stated)"
# (a) generalisation: only setting 2's SR is printed as a number (49 %); (b) scaling: the end points 5 -> 1,000 scenes.
PAPER_ABLATION_GENERALISATION: dict[str, dict[str, float]] = {"2": {"sr": 0.49}}
PAPER_ABLATION_SCALING: dict[int, dict[str, float]] = {5: {"sr": 0.12}, 1000: {"sr": 0.46}}
