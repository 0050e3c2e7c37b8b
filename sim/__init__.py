"""The simulator: scene generation (sim.scene), PyBullet world, machines, sensors, agents, tasks, metrics, envs.

Importing `sim` registers the Gymnasium environments `curbside/PointNav-v0` and `curbside/SocialNav-v0`
(entry points are strings, so nothing heavy loads; see sim.envs.ENV_IDS).
"""

from kernel.quiet import import_pybullet

import_pybullet()  # first, before any sim module imports pybullet: its build-time banner is noise on every command

from sim.envs import ENV_IDS, register_envs  # noqa: E402

register_envs()

__all__ = ["ENV_IDS", "register_envs"]
