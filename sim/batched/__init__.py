"""Batched PointNav: many envs stepped in one vectorised numpy pass (docs/batched.md).

`BatchedPointNav(num_envs, config)` is a `gymnasium.vector.VectorEnv`; it is also the vector entry point of
`curbside/PointNav-v0`: `gymnasium.make_vec("curbside/PointNav-v0", num_envs=64, vectorization_mode="vector_entry_point")`.
PyBullet (`sim.envs.pointnav.PointNavEnv`) stays the reference and the env for terrain and contact-rich work.
"""

from sim.batched.env import BatchedPointNav

__all__ = ["BatchedPointNav"]
