"""Gymnasium environments: PointNav (sim.envs.pointnav) and SocialNav (sim.envs.socialnav).

`register_envs()` registers the ids (and curbside/BatchedPointNav-v0 and BatchedSocialNav-v0, vector only); `import sim` calls it, and so does code that makes envs by id
(entry points are strings, so nothing heavy loads).
"""

from gymnasium.envs.registration import register, registry

ENV_IDS = {
    "curbside/PointNav-v0": "sim.envs.pointnav:PointNavEnv",
    "curbside/SocialNav-v0": "sim.envs.socialnav:SocialNavEnv",
}
# Vector-only ids: `gymnasium.make_vec(id, num_envs)` gives the batched numpy env (docs/batched.md: flat ground,
# kinematic machines); it has no single-env `gymnasium.make`. `make_vec` of the ids above gives PyBullet envs.
VECTOR_ENTRY_POINTS = {
    "curbside/BatchedPointNav-v0": "sim.batched:BatchedPointNav",
    "curbside/BatchedSocialNav-v0": "sim.batched:BatchedSocialNav",
}


def register_envs() -> None:
    """Register the curbside env ids with Gymnasium (idempotent)."""
    for env_id, entry_point in ENV_IDS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point)
    for env_id, vector_entry_point in VECTOR_ENTRY_POINTS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=None, vector_entry_point=vector_entry_point)
