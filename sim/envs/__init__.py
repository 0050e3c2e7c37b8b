"""Gymnasium environments: PointNav (sim.envs.pointnav) and SocialNav (sim.envs.socialnav).

`register_envs()` registers both ids; `import sim` calls it, and so does code that makes envs by id
(entry points are strings, so nothing heavy loads).
"""

from gymnasium.envs.registration import register, registry

ENV_IDS = {
    "curbside/PointNav-v0": "sim.envs.pointnav:PointNavEnv",
    "curbside/SocialNav-v0": "sim.envs.socialnav:SocialNavEnv",
}
# `gymnasium.make_vec(id, num_envs, vectorization_mode="vector_entry_point")` (also make_vec's default mode when an
# id has one): the batched numpy env (docs/batched.md); "sync"/"async" give PyBullet envs.
VECTOR_ENTRY_POINTS = {"curbside/PointNav-v0": "sim.batched:BatchedPointNav"}


def register_envs() -> None:
    """Register the curbside env ids with Gymnasium (idempotent)."""
    for env_id, entry_point in ENV_IDS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point, vector_entry_point=VECTOR_ENTRY_POINTS.get(env_id))
