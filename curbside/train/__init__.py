"""Training harness: online RL (PPO, PPO-Lag, PPO-ET on Stable-Baselines3), offline RL (IQL, TD3+BC) and imitation
(BC, GAIL) in plain torch, expert demonstrations as Minari datasets, and split evaluation.

Everything heavy (torch, SB3, minari) is imported inside the functions that need it, so `curbside --help` and the
simulator stay light.
"""
