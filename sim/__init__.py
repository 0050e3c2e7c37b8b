"""The simulator: scene generation (sim.scene), PyBullet world, machines, sensors, agents, tasks, metrics, envs.

Importing `sim` registers the Gymnasium environments (entry points are strings, so nothing heavy loads).
"""

from gymnasium.envs.registration import register, registry

_ENVS = {
    "curbside/PointNav-v0": "sim.envs.pointnav:PointNavEnv",
    "curbside/SocialNav-v0": "sim.envs.socialnav:SocialNavEnv",
}

for _env_id, _entry_point in _ENVS.items():
    if _env_id not in registry:
        register(id=_env_id, entry_point=_entry_point)
