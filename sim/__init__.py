"""The simulator: scene generation (sim.scene), PyBullet world, machines, sensors, agents, tasks, metrics, envs.

Importing `sim` registers the Gymnasium environments `curbside/PointNav-v0` and `curbside/SocialNav-v0` (and the
vector-only `curbside/BatchedPointNav-v0` and `curbside/BatchedSocialNav-v0`); entry points are strings, so nothing heavy loads. Modules import
pybullet as `from kernel.quiet import pybullet as p`, without its build-time banner.
"""

from sim.envs import ENV_IDS, register_envs

register_envs()

__all__ = ["ENV_IDS", "register_envs"]
