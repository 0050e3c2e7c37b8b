"""Tasks: episode definitions (config defaults, reward, scene sources) for the simulator envs."""

# The task a benchmark runs when none is named (sim.bench and `curbside sim bench`).
DEFAULT_TASK = "PointNav"
