"""Tasks: episode definitions (config defaults, reward, scene sources) for the simulator envs."""
