"""Rendering: TinyRenderer camera frames (top-down, chase) and rollout GIFs over the top-down map (`sim/topdown.py`)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from kernel.quiet import pybullet as p

if TYPE_CHECKING:
    from sim.envs.pointnav import PointNavEnv


def camera_image(
    env: Any, camera: str = "top_down", width: int = 128, height: int = 128, top_down_height: float = 25.0
) -> np.ndarray:
    """RGB (H, W, 3) uint8 frame of the env's world from PyBullet's TinyRenderer (CPU, no display)."""
    m = env.machine
    x, y, z = m.position
    if camera == "top_down":
        view = p.computeViewMatrix([x, y, z + top_down_height], [x, y, z], [math.cos(m.yaw), math.sin(m.yaw), 0])
        fov = 60.0
    elif camera == "chase":
        back, up = 3.0 + m.spec.length, 1.5 + 0.5 * m.spec.height
        eye = [x - back * math.cos(m.yaw), y - back * math.sin(m.yaw), z + up]
        target = [x + 2.0 * math.cos(m.yaw), y + 2.0 * math.sin(m.yaw), z + 0.5 * m.spec.height]
        view = p.computeViewMatrix(eye, target, [0, 0, 1])
        fov = 70.0
    else:
        raise ValueError(f"unknown camera {camera!r}; valid: top_down, chase")
    proj = p.computeProjectionMatrixFOV(fov, width / height, 0.1, 200.0)
    _, _, rgba, _, _ = p.getCameraImage(
        width, height, view, proj, renderer=p.ER_TINY_RENDERER, physicsClientId=env.client
    )
    return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy()


def rollout_gif(
    env_id: str,
    policy: str,
    out: Any,
    config: dict | None = None,
    *,
    seed: int = 0,
    chase: bool = True,
    map_px: int = 480,
    fps: int = 10,
) -> dict[str, float]:
    """Run one episode and write a GIF (map with route and growing trajectory, plus chase camera); return metrics."""
    from pathlib import Path

    import gymnasium as gym
    import imageio.v2 as imageio
    from PIL import Image

    from sim.envs import register_envs
    from sim.palette import COLLISION, EGO, TRAJECTORY
    from sim.rollout import make_policy, rollout
    from sim.topdown import Canvas, draw_ego, draw_route, draw_scene

    register_envs()

    env = gym.make(env_id, config=dict(config or {}))
    u = cast("PointNavEnv", env.unwrapped)  # gym.make's type is any Env; curbside's env ids make PointNav-style ones
    frames: list[np.ndarray] = []
    view: dict[str, Any] = {}

    def start(env: Any) -> None:
        route = u.route
        assert route is not None  # on_reset runs after a reset that drew the route
        pts = route.points
        margin = 8.0
        x0, y0 = pts.min(0) - margin
        x1, y1 = pts.max(0) + margin
        side = max(x1 - x0, y1 - y0)  # square view keeps the map undistorted
        cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
        extent = (cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2)
        # The scene and route are drawn once an episode, so supersampled; each frame draws only what moves.
        c = Canvas(extent, map_px / side, ss=3)
        draw_scene(c, u.scene)
        draw_route(c, pts, 3.0, goal=True)
        view.update(extent=extent, px_per_m=map_px / side, bg=c.image())

    def draw_frame(env: Any, done: bool) -> None:
        bg = view["bg"]
        h, w = bg.shape[:2]
        c = Canvas(view["extent"], view["px_per_m"], background=bg)
        c.line(u.episode.trajectory, TRAJECTORY, 3.0)
        m = u.machine
        assert m is not None  # on_step runs after a reset placed the machine
        draw_ego(
            c,
            m.position[0],
            m.position[1],
            m.yaw,
            m.spec.length,
            m.spec.width,
            COLLISION if u.episode.step_collisions else EGO,
            min_px=12.0,
        )
        frame = Image.fromarray(c.image())
        if chase and (u.episode.steps % 2 == 1 or done):
            view["cam"] = Image.fromarray(camera_image(u, "chase", 160, 160)).resize((h, h), Image.Resampling.NEAREST)
        if chase:
            canvas = Image.new("RGB", (w + h, h))
            canvas.paste(frame, (0, 0))
            canvas.paste(view["cam"], (w, 0))
            frame = canvas
        frames.append(np.asarray(frame))

    try:
        metrics = rollout(env, make_policy(policy, env), seed, on_reset=start, on_step=draw_frame)
    finally:
        env.close()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    imageio.mimsave(out, list(frames), duration=1000 / fps, loop=0)  # a list of ArrayLike, as its stub asks
    Image.fromarray(frames[-1]).save(out.with_suffix(".png"))
    return metrics


def rollout_video(
    env_id: str, policy: str, out: Any, config: dict | None = None, *, seed: int = 0, fps: int = 10
) -> dict[str, float]:
    """Run one episode through Gymnasium's RecordVideo (the env's dashboard frames) and write it as MP4 to `out`."""
    import shutil
    import tempfile
    from pathlib import Path

    import gymnasium as gym

    from sim.envs import register_envs
    from sim.rollout import make_policy, rollout

    try:
        import moviepy  # noqa: F401
    except ImportError:
        raise ValueError("writing a video needs moviepy: pip install 'curbside[viewer]'") from None
    register_envs()
    out = Path(out)
    with tempfile.TemporaryDirectory() as tmp:
        env = gym.make(env_id, config=dict(config or {}), render_mode="rgb_array")
        env = gym.wrappers.RecordVideo(
            env, f"{tmp}/video", episode_trigger=lambda _: True, name_prefix="rollout", fps=fps
        )
        try:
            metrics = rollout(env, make_policy(policy, env.unwrapped), seed)
        finally:
            env.close()
        (video,) = Path(tmp, "video").glob("rollout-episode-0.mp4")
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(str(video), out)
    return metrics
