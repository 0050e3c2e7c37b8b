"""Rendering: TinyRenderer camera frames (top-down, chase) and a matplotlib top-down map for GIFs."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pybullet as p


def camera_image(env: Any, camera: str = "top_down", width: int = 128, height: int = 128,
                 top_down_height: float = 25.0) -> np.ndarray:
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
    _, _, rgba, _, _ = p.getCameraImage(width, height, view, proj, renderer=p.ER_TINY_RENDERER,
                                        physicsClientId=env.client)
    return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy()


def _map_background(spec: dict, route_pts: np.ndarray, extent: tuple[float, float, float, float],
                    px: int) -> np.ndarray:
    """A top-down matplotlib drawing of the scene's surfaces, objects and the route, as an RGB array."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon as MplPolygon

    from sim.palette import LANE_LINE, ROUTE, SURFACE, category_color

    x0, y0, x1, y1 = extent
    fig = plt.figure(figsize=(px / 100, px * (y1 - y0) / (x1 - x0) / 100), dpi=100, facecolor=SURFACE["ground"][:3])
    ax = fig.add_axes([0, 0, 1, 1])
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_facecolor(SURFACE["ground"][:3])
    ax.axis("off")

    def poly(pts, color, z):
        ax.add_patch(MplPolygon(np.asarray(pts), closed=True, facecolor=color[:3], edgecolor="none", zorder=z))

    for road in spec["roads"]:
        poly(road["polygon"], SURFACE["road"], 1)
        for line in road.get("lane_lines", []):
            ln = np.asarray(line)
            ax.plot(ln[:, 0], ln[:, 1], color=LANE_LINE, lw=0.6, dashes=(4, 4), zorder=2)
    for sw in spec["sidewalks"]:
        poly(sw["polygon"], SURFACE["sidewalk"], 2)
        for zone in sw.get("zones", []):
            if zone.get("kind") == "building":
                poly(zone["polygon"], SURFACE["building"], 2)
    for cw in spec["crosswalks"]:
        poly(cw["polygon"], SURFACE["crosswalk"], 3)
        for ramp in cw.get("ramps", []):
            poly(ramp["polygon"], SURFACE["ramp"], 3)
    for obj in spec["objects"]:
        poly(obj["footprint"], category_color(str(obj.get("category", "object"))), 4)
    ax.plot(route_pts[:, 0], route_pts[:, 1], color=ROUTE, lw=2.0, zorder=5)
    ax.plot(*route_pts[-1], marker="*", color=ROUTE, markersize=14, zorder=6)
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[:, :, :3].copy()
    plt.close(fig)
    return img


def rollout_gif(env_id: str, policy: str, out: Any, config: dict | None = None, *, seed: int = 0,
                chase: bool = True, map_px: int = 480, fps: int = 10) -> dict[str, float]:
    """Run one episode and write a GIF (map with route and growing trajectory, plus chase camera); return metrics."""
    from pathlib import Path

    import gymnasium as gym
    import imageio.v2 as imageio
    from PIL import Image, ImageDraw

    from sim.envs import register_envs
    from sim.rollout import make_policy, rollout

    register_envs()

    env = gym.make(env_id, config=dict(config or {}))
    u = env.unwrapped
    frames: list[np.ndarray] = []
    view: dict[str, Any] = {}

    def start(env: Any) -> None:
        pts = u.route.points
        margin = 8.0
        x0, y0 = pts.min(0) - margin
        x1, y1 = pts.max(0) + margin
        side = max(x1 - x0, y1 - y0)  # square view keeps the map undistorted
        cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
        extent = (cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2)
        view.update(side=side, extent=extent, bg=_map_background(u.scene_spec, pts, extent, map_px))

    def draw_frame(env: Any, done: bool) -> None:
        side, extent, bg = view["side"], view["extent"], view["bg"]
        h, w = bg.shape[:2]

        def to_px(x: float, y: float) -> tuple[float, float]:
            return ((x - extent[0]) / side * w, (extent[3] - y) / side * h)

        frame = Image.fromarray(bg)
        draw = ImageDraw.Draw(frame)
        traj = [to_px(x, y) for x, y in u.episode.trajectory]
        if len(traj) > 1:
            draw.line(traj, fill=(30, 110, 255), width=3)
        ex, ey = traj[-1]
        r = max(3.0, u.machine.spec.length / side * w)
        color = (255, 60, 60) if u.episode.step_collisions else (255, 150, 20)
        draw.ellipse([ex - r, ey - r, ex + r, ey + r], fill=color)
        hx, hy = to_px(u.machine.position[0] + 2.0 * np.cos(u.machine.yaw), u.machine.position[1] + 2.0 * np.sin(u.machine.yaw))
        draw.line([(ex, ey), (hx, hy)], fill=(20, 20, 20), width=2)
        if chase and (u.episode.steps % 2 == 1 or done):
            view["cam"] = Image.fromarray(camera_image(u, "chase", 160, 160)).resize((h, h), Image.NEAREST)
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
    imageio.mimsave(out, frames, duration=1000 / fps, loop=0)
    Image.fromarray(frames[-1]).save(out.with_suffix(".png"))
    return metrics
