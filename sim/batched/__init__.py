"""Batched PointNav: many envs stepped in one vectorised numpy pass (docs/batched.md).

`BatchedPointNav(num_envs, config)` is a `gymnasium.vector.VectorEnv`; it is registered as the vector-only id
`curbside/BatchedPointNav-v0`: `gymnasium.make_vec("curbside/BatchedPointNav-v0", num_envs=64)`.
PyBullet (`sim.envs.pointnav.PointNavEnv`) stays the reference and the env for terrain and contact-rich work.
"""

from sim.batched.env import BatchedPointNav

__all__ = ["BatchedPointNav"]
