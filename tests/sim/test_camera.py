"""The ego camera: Dict observations, metric depth and semantic ids checked against Bullet rays, determinism, errors."""

from __future__ import annotations

import math
import os

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest

from kernel.config import ConfigError
from sim.camera import SEMANTIC_CLASSES, SEMANTIC_ID, linear_depth
from sim.envs import register_envs

register_envs()
ALL = ["rgb", "depth", "semantic"]


def _env(modalities: list[str], size: int = 48, env_id: str = "curbside/PointNav-v0", **extra) -> gym.Env:
    return gym.make(env_id, config={"camera": {"modalities": modalities, "width": size, "height": size}, **extra})


def test_dict_observation_holds_the_vector_parts_and_the_images() -> None:
    env = _env(ALL)
    obs, _ = env.reset(seed=3)
    space = env.observation_space
    assert isinstance(space, gym.spaces.Dict) and set(space) == {"lidar", "state", "nav", *ALL}
    assert space.contains(obs)
    assert obs["rgb"].shape == (48, 48, 3) and obs["rgb"].dtype == np.uint8
    assert obs["depth"].shape == (48, 48, 1) and obs["depth"].dtype == np.float32
    assert obs["semantic"].shape == (48, 48) and obs["semantic"].max() < len(SEMANTIC_CLASSES)
    # The vector parts are the flat observation split in three.
    flat = gym.make("curbside/PointNav-v0")
    ref, _ = flat.reset(seed=3)
    np.testing.assert_array_equal(np.concatenate([obs["lidar"], obs["state"], obs["nav"]]), ref)
    for _ in range(3):
        obs, *_ = env.step(np.array([0.1, 0.6], dtype=np.float32))
        assert space.contains(obs)
    # Looking ahead and down from the sidewalk, the camera sees the sidewalk.
    assert (obs["semantic"] == SEMANTIC_ID["sidewalk"]).mean() > 0.1
    env.close()
    flat.close()


def _pixel_rays(env: gym.Env) -> list[tuple[float, int]]:
    """Depth along the optical axis and body hit by Bullet rays from the eye through the centre pixel's corners
    (TinyRenderer samples a pixel half a pixel off its centre; near the horizon depth changes fast per row)."""
    u = env.unwrapped
    cam, m = u.camera, u.machine
    view = np.array(cam.view(m)).reshape(4, 4, order="F")
    rot, t = view[:3, :3], view[:3, 3]
    eye = -rot.T @ t
    right, up, forward = rot[0], rot[1], -rot[2]  # OpenGL cameras look down -z
    f = cam.intrinsics[0, 0]
    out = []
    for du in (-0.5, 0.5):
        for dv in (-0.5, 0.5):
            d = forward + (du * right + dv * up) / f
            d /= np.linalg.norm(d)
            hit = p.rayTest(eye.tolist(), (eye + cam.far * d).tolist(), physicsClientId=u.client)[0]
            out.append((hit[2] * cam.far * float(d @ forward), hit[0]))
    return out


@pytest.mark.parametrize("seed", [0, 5])
def test_depth_is_metric_and_semantic_names_the_body_a_ray_hits(seed: int) -> None:
    env = _env(ALL, size=65)  # odd: the centre pixel lies on the optical axis
    obs, _ = env.reset(seed=seed)
    for _ in range(5):
        obs, *_ = env.step(np.array([0.0, 0.4], dtype=np.float32))
    rays = _pixel_rays(env)
    u = env.unwrapped
    depths = [d for d, _ in rays]
    assert min(depths) - 0.02 <= obs["depth"][32, 32, 0] <= max(depths) + 0.02, (obs["depth"][32, 32, 0], depths)
    names = set()
    for _, body in rays:
        kind = u.world.kinds.get(body)
        names.add(u.world.object_category(body) if kind == "object" else kind)
    assert SEMANTIC_CLASSES[obs["semantic"][32, 32]] in names
    env.close()


def test_linear_depth_inverts_the_opengl_depth_buffer() -> None:
    near, far = 0.05, 50.0
    z = np.array([0.05, 1.0, 7.5, 50.0])
    ndc = (far + near) / (far - near) - 2 * far * near / ((far - near) * z)  # OpenGL's projection of eye depth z
    np.testing.assert_allclose(linear_depth(0.5 * ndc + 0.5, near, far), z, rtol=1e-4)


def test_the_same_seed_renders_the_same_images() -> None:
    runs = []
    for _ in range(2):
        env = _env(ALL, size=32)
        obs, _ = env.reset(seed=11)
        obs, *_ = env.step(np.array([0.3, 0.5], dtype=np.float32))
        runs.append(obs)
        env.close()
    for k in ALL:
        assert runs[0][k].tobytes() == runs[1][k].tobytes()


def test_socialnav_agents_and_vehicles_have_their_own_classes() -> None:
    env = _env(["semantic"], size=32, env_id="curbside/SocialNav-v0")
    env.reset(seed=0)
    u = env.unwrapped
    agent, vehicle = u.bodies.agents[0], u.bodies.vehicles[0]
    mask = np.array([[agent, vehicle], [u.machine.body, -1]])
    got = u.camera.classes(mask, u.machine.body, u._collision_kinds)
    assert [SEMANTIC_CLASSES[i] for i in got.ravel()] == ["agent", "vehicle", "ego", "unlabeled"]
    env.close()


def test_flat_observation_without_camera_is_unchanged() -> None:
    env = gym.make("curbside/PointNav-v0")
    assert isinstance(env.observation_space, gym.spaces.Box)
    env.close()


@pytest.mark.parametrize(
    ("config", "message"),
    [
        ({"camera": {"modalities": ["thermal"]}}, "thermal"),
        ({"camera": {"modalities": ["rgb"]}, "observation": "flat"}, "observation 'flat' cannot hold camera images"),
        ({"camera": {"modalities": ["rgb"], "fov": 0.0}}, "fov"),
        ({"camera": {"modalities": ["rgb"], "zoom": 2}}, "unknown key 'zoom'"),
    ],
)
def test_bad_camera_configs_name_the_problem(config: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        gym.make("curbside/PointNav-v0", config=config)


@pytest.mark.skipif(
    any(os.path.exists(f"/dev/nvidia{k}") for k in range(8)) or os.path.exists("/dev/dri/renderD128"),
    reason="a GPU is present: EGL may load",
)
def test_egl_without_a_gpu_says_so() -> None:
    env = gym.make("curbside/PointNav-v0", config={"camera": {"modalities": ["rgb"], "renderer": "egl"}})
    with pytest.raises(ConfigError, match="needs a GPU with EGL"):
        env.reset(seed=0)
    env.close()


def test_the_batched_env_refuses_cameras() -> None:
    with pytest.raises(ConfigError, match="nothing to render"):
        gym.make_vec("curbside/BatchedPointNav-v0", num_envs=2, config={"camera": {"modalities": ["rgb"]}})


def test_intrinsics_match_the_field_of_view() -> None:
    env = _env(["depth"], size=64)
    env.reset(seed=0)
    k = env.unwrapped.camera.intrinsics
    assert k[0, 0] == pytest.approx(32 / math.tan(math.radians(45)))
    env.close()


@pytest.mark.parametrize("seed", [1, 4])
def test_depth_along_the_centre_row_matches_the_lidar(seed: int) -> None:
    # A level camera sees along its centre row what a LiDAR at the same point and height measures along its beams.
    from sim.sensors import Lidar

    height = 0.4
    cam = {"modalities": ["depth"], "width": 161, "height": 33, "fov": 60.0, "mount_height": height, "pitch": 0.0}
    env = gym.make("curbside/PointNav-v0", config={"camera": cam})
    obs, _ = env.reset(seed=seed)
    for _ in range(8):
        obs, *_ = env.step(np.array([0.2, 0.5], dtype=np.float32))
    u = env.unwrapped
    m, f = u.machine, u.camera.intrinsics[0, 0]
    x, y, z = m.position
    ex, ey = x + 0.5 * m.spec.length * math.cos(m.yaw), y + 0.5 * m.spec.length * math.sin(m.yaw)
    lidar = Lidar(u.client, beams=720, range_m=50.0, height=height, start_radius=0.05)
    d = lidar.scan(ex, ey, z, m.yaw).astype(np.float64) * lidar.range_m
    angles = np.arctan2(np.sin(lidar.angles), np.cos(lidar.angles))
    seen = (np.abs(np.tan(angles)) * f < 75) & (np.abs(angles) < math.pi / 2) & (d < 0.99 * lidar.range_m)
    # TinyRenderer samples pixel (r, c) at its corner (r, c), not its centre: the optical axis, at 80.5 across
    # and 16.5 down, falls between rows 15 and 16, and a point at tan(angle) left of it lies at 80.5 - f tan(angle).
    cols = np.clip(np.rint(80.5 - f * np.tan(angles[seen])).astype(int), 0, 160)
    expected = d[seen] * np.cos(angles[seen])  # depth is measured along the optical axis
    # Row 16 looks a fraction of a degree down (the ground beyond ~23 m), row 15 as much up: the beam is between.
    got = np.maximum(obs["depth"][15, cols, 0], obs["depth"][16, cols, 0])
    close = np.abs(got - expected) <= 0.1 + 0.05 * expected
    # A beam and its pixel sample a surface a fraction of a degree apart: at an edge, or along a wall seen at a
    # grazing angle, one of them may land elsewhere.
    assert seen.sum() >= 40 and close.mean() >= 0.85, (close.mean(), seen.sum())
    env.close()


def test_check_env_passes_with_the_dict_space() -> None:
    from gymnasium.utils.env_checker import check_env

    env = _env(ALL, size=32)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_depth_never_exceeds_the_far_plane() -> None:
    assert float(linear_depth(np.array([1.0]), 0.05, 50.0)[0]) <= 50.0


def test_semantic_classes_follow_bodies_that_change_kind() -> None:
    # SocialNav removes and re-adds bodies; Bullet hands freed ids to new ones: the table follows the kinds.
    env = _env(["semantic"], size=16)
    env.reset(seed=0)
    u = env.unwrapped
    mask = np.array([[900, 901]])
    first = u.camera.classes(mask, u.machine.body, {900: "agent", 901: "vehicle"})
    second = u.camera.classes(mask, u.machine.body, {900: "vehicle", 901: "agent"})
    assert [SEMANTIC_CLASSES[i] for i in first.ravel()] == ["agent", "vehicle"]
    assert [SEMANTIC_CLASSES[i] for i in second.ravel()] == ["vehicle", "agent"]
    env.close()
