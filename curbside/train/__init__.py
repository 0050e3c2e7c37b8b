"""Training harness: online RL (PPO, PPO-Lag, PPO-ET on Stable-Baselines3), offline RL (IQL, TD3+BC on d3rlpy),
imitation (BC, GAIL on `imitation`), expert demonstrations as Minari datasets, and split evaluation.

Everything heavy (torch, SB3, d3rlpy, imitation, minari) is imported inside the functions that need it, so
`curbside --help` and the simulator stay light.
"""
