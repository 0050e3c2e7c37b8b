"""Task design that learns: per-step cost, stuck endings, reward presets, geodesic SPL, surface PSC, splits, cache."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kernel.config import ConfigError
from sim.envs.pointnav import PointNavEnv
from sim.envs.socialnav import SocialNavEnv
from sim.expert import PurePursuitExpert


def _drive(env, policy, seed=0, options=None):
    obs, _ = env.reset(seed=seed, options=options)
    infos = []
    while True:
        obs, r, term, trunc, info = env.step(policy(env))
        infos.append(info)
        if term or trunc:
            return infos


def test_per_step_cost_is_0_or_1_on_every_step_including_the_last(spec):
    # Straight into the trash bin at x = 15 and stay there: many cost steps, the last one among them.
    env = PointNavEnv(
        {
            "scene_spec": spec,
            "out_of_route_distance": 50.0,
            "terminate_off_walkable": False,
            "stuck_steps": 0,
            "collision_steps": 0,
            "horizon": 60,
        }
    )
    infos = _drive(env, lambda e: [0.0, 1.0], options={"start": [10.0, 7.0], "goal": [25.0, 7.0]})
    costs = [i["cost"] for i in infos]
    assert set(costs) <= {0.0, 1.0} and costs[-1] == 1.0
    assert infos[-1]["episode_cost"] == sum(costs) > 1  # the total has its own key
    assert infos[-1]["metrics"]["cost"] == sum(costs)


def test_curb_contact_is_not_a_cost_but_is_counted(spec):
    env = PointNavEnv(
        {"scene_spec": spec, "out_of_route_distance": 50.0, "terminate_off_walkable": False, "horizon": 30}
    )
    env.reset(seed=0, options={"start": [12.0, 7.0], "goal": [25.0, 7.0]})
    env.machine.reset(10.0, 2.0, 0.0, math.pi / 2, env.np_random)
    infos = [env.step([0.0, 0.6])[4] for _ in range(20)]
    assert any("curb" in i["collision_kinds"] for i in infos)
    assert all(i["cost"] == 0.0 for i in infos)  # the paper's cost: objects and buildings


def test_a_machine_pinned_against_an_object_ends_its_episode_as_stuck(spec):
    env = PointNavEnv(
        {
            "scene_spec": spec,
            "out_of_route_distance": 50.0,
            "terminate_off_walkable": False,
            "collision_steps": 25,
            "stuck_steps": 0,
        }
    )
    infos = _drive(env, lambda e: [0.0, 1.0], options={"start": [10.0, 7.0], "goal": [25.0, 7.0]})
    assert infos[-1]["stuck"] and not infos[-1]["is_success"] and len(infos) < 100


def test_standing_still_ends_the_episode_and_costs_more_than_driving(spec):
    env = PointNavEnv({"scene_spec": spec, "stuck_steps": 50})
    still = _drive(env, lambda e: [0.0, 0.0], seed=3)
    assert still[-1]["stuck"] and len(still) == 50
    env.reset(seed=3)
    total_still = 0.0
    for _ in range(50):
        total_still += env.step([0.0, 0.0])[1]
    env.reset(seed=3)
    expert, total_expert, done = PurePursuitExpert(), 0.0, False
    while not done:
        _, r, term, trunc, _ = env.step(expert.act(env))
        total_expert += r
        done = term or trunc
    assert total_still < 0.0 < total_expert


def test_going_back_and_forth_earns_nothing_with_the_learnable_reward(spec):
    env = PointNavEnv({"scene_spec": spec})
    env.reset(seed=0)
    s0 = env.episode.max_progress
    from sim.tasks.termination import StepContext, StepEnd

    back_again = StepContext(
        steps=2,
        progress=1.0,
        new_progress=0.0,
        max_progress=1.0,
        route_length=20.0,
        lateral=0.0,
        d_steer=0.0,
        speed=1.0,
        tilt=0.0,
        collided=False,
        in_contact=False,
        cost_total=0.0,
        on_walkable=lambda: True,
    )
    gain = env.reward_fn(back_again, StepEnd())
    assert gain == 0.0 and s0 == 0.0
    paper = PointNavEnv({"scene_spec": spec, "reward_preset": "paper"})
    assert paper.reward_fn.progress == "route" and paper.reward_fn.lateral == 1.0 and paper.reward_fn.disp == 0.5
    with pytest.raises(ConfigError, match="valid: paper, learnable"):
        PointNavEnv({"scene_spec": spec, "reward_preset": "easy"})
    with pytest.raises(ConfigError, match="valid keys"):
        PointNavEnv({"scene_spec": spec, "reward": {"bonus": 1.0}})


def test_horizon_follows_the_route_length(spec):
    env = PointNavEnv({"scene_spec": spec, "route_length": [10.0, 20.0], "horizon_min_speed": 0.5})
    _, info = env.reset(seed=0)
    assert info["horizon"] == math.ceil(info["route_length"] / 0.5 / 0.1) < 1000


def test_expert_cutting_no_corner_scores_spl_below_one_on_a_turning_route(spec):
    # From the left sidewalk across the crosswalk (x 28..31) to the right sidewalk: two 90-degree turns.
    env = PointNavEnv({"scene_spec": spec})
    infos = _drive(env, PurePursuitExpert().act, options={"start": [20.0, 6.5], "goal": [40.0, -6.5]})
    m = infos[-1]["metrics"]
    assert m["success"] == 1.0
    geodesic = env.reference_length()
    assert geodesic < 0.95 * env.route.length  # the taut path cuts the route's corners
    assert m["spl"] < 0.99 and m["spl"] == pytest.approx(geodesic / m["path_length"])


def test_geodesic_of_a_straight_route_is_its_length(spec):
    env = PointNavEnv({"scene_spec": spec})
    env.reset(seed=0, options={"start": [2.0, 6.5], "goal": [12.0, 6.5]})
    assert env.reference_length() == pytest.approx(0.95 * env.route.length, rel=0.02)


def test_psc_falls_below_one_when_an_agent_enters_the_personal_space(spec):
    cfg = {"scene_spec": spec, "traffic": False, "agents": {"counts": {"pedestrian": 1}}, "horizon": 4}
    env = SocialNavEnv(cfg)
    env.reset(seed=0)
    m = env.machine
    x, y, _ = m.position
    # An agent 0.2 m in front of the ego's bumper: inside the 0.45 m personal space between body surfaces.
    ax, ay = (
        x + math.cos(m.yaw) * (0.5 * m.spec.length + 0.2 + 0.3),
        y + math.sin(m.yaw) * (0.5 * m.spec.length + 0.2 + 0.3),
    )
    env.crowd.pos[0] = (ax, ay)
    env.crowd.orca.pos[0] = (ax, ay)
    infos = [env.step([0.0, -1.0])[4] for _ in range(4)]
    assert infos[-1]["psc"] < 1.0 and infos[-1]["sns"] < 1.0
    # Without agents PSC is 1 and the metric does not fire.
    env2 = SocialNavEnv({**cfg, "agents": {"counts": {}, "dynamic_density": 0.0}})
    env2.reset(seed=0)
    infos2 = [env2.step([0.0, -1.0])[4] for _ in range(4)]
    assert infos2[-1]["psc"] == 1.0


def test_split_configs_draw_disjoint_scenes():
    seeds = {}
    for split in ("train", "test", "unseen", "finetune"):
        env = PointNavEnv({"split": split, "num_scenes": 3, "scene_cache": 3, "route_length": [5.0, 30.0]})
        drawn = set()
        for s in range(8):
            env.reset(seed=s)
            drawn.add(env.slot.key)
        seeds[split] = {k[2] for k in drawn}
        templates = {sw["template"] for sw in env.scene_spec["sidewalks"] if "template" in sw}
        if split in ("unseen", "finetune") and templates:
            assert templates == {"g"}
        env.close()
    splits = list(seeds)
    for i, a in enumerate(splits):
        for b in splits[i + 1 :]:
            assert not seeds[a] & seeds[b], (a, b)
    with pytest.raises(ConfigError, match="valid: train, test, unseen, finetune"):
        PointNavEnv({"split": "validation"})


def test_scene_cache_reuses_worlds_and_episodes_do_not_depend_on_it(random_trace):
    cfg = {"num_scenes": 3, "route_length": [5.0, 30.0]}
    cached = PointNavEnv({**cfg, "scene_cache": 3})
    fresh = PointNavEnv({**cfg, "scene_cache": 1})
    worlds = {}
    for s in range(6):
        cached.reset(seed=s)
        worlds.setdefault(cached.slot.key, set()).add(id(cached.world))
    assert all(len(v) == 1 for v in worlds.values())  # a repeated scene is not rebuilt
    assert len(cached.cache.slots) <= 3
    for s in (4, 1, 5):
        a, b = random_trace(cached, s, 15), random_trace(fresh, s, 15)
        assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
    cached.close()
    fresh.close()


def test_socialnav_cache_keeps_each_worlds_agents():
    env = SocialNavEnv({"num_scenes": 2, "scene_cache": 2, "route_length": [5.0, 30.0], "traffic": False})
    keys = []
    for s in range(5):
        env.reset(seed=s)
        for _ in range(3):
            env.step([0.0, 0.5])
        keys.append(env.slot.key)
        assert len(env.bodies.agents) == env.crowd.n
    assert len(set(keys)) == 2
    env.close()


def test_scene_steps_keep_a_scene_for_that_many_steps_then_draw_another():
    """scene_steps 10, episodes of 4 steps: the resets at 0, 4 and 8 steps share a scene (and its world and crowd), the
    one at 12 draws the next; every reset plans a new route. Evaluation's scene_steps 0 draws at every reset."""
    cfg = {"num_scenes": 50, "scene_cache": 1, "route_length": [5.0, 30.0], "traffic": False}
    env = SocialNavEnv({**cfg, "scene_steps": 10})
    keys, worlds, starts = [], [], []
    env.reset(seed=3)
    for _ in range(6):
        keys.append(env.slot.key)
        worlds.append(id(env.world))
        starts.append(tuple(np.round(env.route.start, 3)))
        assert len(env.bodies.agents) == env.crowd.n
        for _ in range(4):
            env.step([0.0, 0.3])
        env.reset()
    env.close()
    assert len(set(keys[:3])) == 1 and len(set(worlds[:3])) == 1
    assert len(set(keys[3:])) == 1 and keys[2] != keys[3]
    assert len(set(starts)) == 6
    every = SocialNavEnv(cfg)
    drawn = set()
    for s in range(4):
        every.reset(seed=s)
        drawn.add(every.slot.key)
    every.close()
    assert len(drawn) > 1


def test_dataset_folder_split_with_no_scenes_is_a_clear_error(tmp_path):
    from sim.scene.dataset import build_dataset

    build_dataset("test", 2, tmp_path, base={"blocks": 1})
    env = PointNavEnv({"scene_dir": str(tmp_path), "split": "test", "num_scenes": None, "route_length": [5.0, 20.0]})
    env.reset(seed=0)
    assert env.slot.key[0] == "file"
    env.close()
    with pytest.raises(ConfigError, match="split 'train' has no scenes .*`curbside scenes dataset --split train"):
        PointNavEnv({"scene_dir": str(tmp_path), "split": "train"})


def test_socialnav_start_height_ignores_the_last_episodes_agents(spec):
    cfg = {"scene_spec": spec, "traffic": False, "agents": {"counts": {"pedestrian": 6}}}
    used = SocialNavEnv(cfg)
    used.reset(seed=0)
    for _ in range(5):
        used.step([0.0, 0.5])
    x, y = (float(v) for v in used.crowd.pos[0])
    options = {"start": [x, y], "goal": [x + 15.0 if x < 40 else x - 15.0, y]}
    used.reset(seed=1, options=options)
    fresh = SocialNavEnv(cfg)
    fresh.reset(seed=1, options=options)
    assert used.machine.position[2] == pytest.approx(fresh.machine.position[2], abs=1e-6)
    assert fresh.machine.position[2] < 0.5  # on the sidewalk, not on a pedestrian's head
    used.close()
    fresh.close()


def test_a_scene_without_a_route_of_the_asked_length_is_swapped_for_another(tmp_path):
    """A 1-block scene holds no 150-200 m route; in a folder beside a 4-block scene, every reset of the PyBullet
    and the batched env lands in the large scene instead of failing. Alone, the small scene still fails clearly."""
    import shutil

    from sim.batched import BatchedPointNav
    from sim.route import RouteError
    from sim.scene.dataset import build_dataset

    build_dataset("test", 2, tmp_path / "mixed", base={"blocks": 1})
    build_dataset("test", 1, tmp_path / "large", base={"blocks": 4})
    small, second = sorted((tmp_path / "mixed" / "scenes").glob("*.json"))
    shutil.copy(tmp_path / "large" / "scenes" / "test_01000000.json", second)
    cfg = {"scene_dir": str(tmp_path / "mixed"), "split": "test", "num_scenes": None, "route_length": [150.0, 200.0]}
    env = PointNavEnv(cfg)
    for seed in range(4):
        _, info = env.reset(seed=seed)
        assert env.slot.key[1].endswith(second.name) and 150.0 <= info["route_length"] <= 200.0
    env.close()
    batched = BatchedPointNav(3, {**cfg, "scene_steps": 1})
    _, info = batched.reset(seed=0)
    for _ in range(3):
        assert all(150.0 <= length <= 200.0 for length in info["route_length"])
        assert all(b.key[1].endswith(second.name) for b in batched.built)
        _, info = batched.reset()
    batched.close()
    alone = PointNavEnv({"scene_path": str(small), "route_length": [150.0, 200.0]})
    with pytest.raises(RouteError, match="no route between 150.0 and 200.0 m"):
        alone.reset(seed=0)
    alone.close()


def test_episode_end_rules_give_the_same_flags_for_one_env_and_for_many():
    """end_of_step on arrays of n (the batched env) and on numbers (the PyBullet env's Termination), over random
    steps that hit every rule, agree flag for flag and mark for mark."""
    from sim.tasks.termination import EndMarks, EndRules, end_of_step

    rules = EndRules(0.95, 2.0, 0.5, 6, 4, True, 1.0, 3.0, building_contact_ends=True)
    rng = np.random.default_rng(0)
    n, many, ones = 64, EndMarks.zeros(64), [EndMarks() for _ in range(64)]
    steps, progress, cost = np.zeros(n, dtype=np.int64), np.zeros(n), np.zeros(n, dtype=np.int64)
    seen = np.zeros(6, dtype=int)
    for _ in range(40):
        steps += 1
        progress = np.maximum(progress, progress + rng.choice([0.0, 0.2, 1.5], n))
        lateral, tilt = rng.normal(0, 1.2, n), rng.uniform(0, 1.2, n)
        walkable, contact = rng.random(n) > 0.05, rng.random(n) > 0.6
        building = contact & (rng.random(n) > 0.9)
        cost += contact
        arrays = end_of_step(
            rules, many, steps, progress, np.full(n, 30.0), lateral, walkable, contact, tilt, cost, building
        )
        for k in range(n):
            one = end_of_step(
                rules,
                ones[k],
                int(steps[k]),
                float(progress[k]),
                30.0,
                float(lateral[k]),
                bool(walkable[k]),
                bool(contact[k]),
                float(tilt[k]),
                int(cost[k]),
                bool(building[k]),
            )
            assert tuple(bool(a[k]) for a in arrays) == tuple(bool(o) for o in one)
            assert (ones[k].step, ones[k].progress, ones[k].contact_run) == (
                many.step[k],
                many.progress[k],
                many.contact_run[k],
            )
        seen += np.array([a.sum() for a in arrays])
    assert (seen > 0).all()  # every rule fired somewhere


def test_out_of_route_ends_false_lets_the_machine_leave_and_keeps_every_other_end():
    """With `out_of_route_ends` false, a step off the route or off the walkable area ends nothing; success, stuck and
    toppling still end the episode, and the same step with the default rules is out of route."""
    from sim.tasks.termination import EndMarks, EndRules, end_of_step

    ends = EndRules(0.95, 2.0, 0.5, 6, 0, True, 1.0, math.inf)
    stays = EndRules(0.95, 2.0, 0.5, 6, 0, True, 1.0, math.inf, out_of_route_ends=False)
    off = (1, 5.0, 30.0, 4.0, False, False, 0.0, 0)  # 4 m off a 2 m route band, off the walkable area
    assert end_of_step(ends, EndMarks(), *off)[1]
    assert end_of_step(stays, EndMarks(), *off) == (False, False, False, False, False, False)
    assert end_of_step(stays, EndMarks(), 1, 29.0, 30.0, 4.0, False, False, 0.0, 0)[0]  # success off the route
    assert end_of_step(stays, EndMarks(), 1, 5.0, 30.0, 4.0, False, False, 2.0, 0)[3]  # toppled
    marks = EndMarks()
    flags = [end_of_step(stays, marks, k, 5.0, 30.0, 4.0, False, False, 0.0, 0) for k in range(1, 8)]
    assert [f[2] for f in flags] == [False] * 6 + [True]  # progress last grew at step 1: stuck at step 7
    many = end_of_step(
        stays,
        EndMarks.zeros(3),
        np.ones(3, dtype=np.int64),
        np.full(3, 5.0),
        np.full(3, 30.0),
        np.array([0.0, 4.0, -9.0]),
        np.array([True, False, False]),
        np.zeros(3, dtype=bool),
        np.zeros(3),
        np.zeros(3),
    )
    assert not many[1].any()
