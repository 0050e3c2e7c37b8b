"""Batched PointNav and SocialNav: many envs stepped in one vectorised numpy pass (docs/batched.md).

`BatchedPointNav(num_envs, config)` and `BatchedSocialNav(num_envs, config)` are `gymnasium.vector.VectorEnv`s,
registered as the vector-only ids `curbside/BatchedPointNav-v0` and `curbside/BatchedSocialNav-v0`:
`gymnasium.make_vec("curbside/BatchedSocialNav-v0", num_envs=64)`. PyBullet (`sim.envs`) stays the reference and
the env for terrain and contact-rich work.
"""

from sim.batched.env import BatchedPointNav
from sim.batched.social import BatchedSocialNav

__all__ = ["BatchedPointNav", "BatchedSocialNav"]
