"""What `env.render()` draws and where "human" mode shows it: the dashboard (chase camera, map around the ego,
the ego camera's images, live metrics), the agents' map, or a plain TinyRenderer camera (docs/cameras.md)."""

from __future__ import annotations

import os
import weakref
from typing import Any

import numpy as np

from kernel.config import ConfigError
from sim.camera import SEMANTIC_CLASSES
from sim.palette import SURFACE, category_color, rgb255

PANEL_BG = (24, 24, 28)
TEXT = (235, 235, 235)
_WINDOWS: weakref.WeakKeyDictionary[Any, HumanWindow] = weakref.WeakKeyDictionary()


def semantic_palette() -> np.ndarray:
    """RGB uint8 colour per semantic id: surfaces and categories in the top-down map's colours."""
    out = np.zeros((len(SEMANTIC_CLASSES), 3), dtype=np.uint8)
    extra = {
        "unlabeled": (0.55, 0.75, 0.95),
        "ground": SURFACE["ground"],
        "agent": (0.9, 0.2, 0.6),
        "vehicle": (0.95, 0.85, 0.1),
        "ego": (0.1, 0.8, 0.9),
    }
    for k, name in enumerate(SEMANTIC_CLASSES):
        colour = extra.get(name) or SURFACE.get(name) or category_color(name)
        out[k] = rgb255(colour)
    return out


_PALETTE = semantic_palette()


def colourise(name: str, image: np.ndarray, far: float = 50.0) -> np.ndarray:
    """An RGB view of one camera modality: rgb as is, depth as grey (near bright, log scale), semantic coloured."""
    if name == "rgb":
        return image
    if name == "depth":
        depth = np.log1p(np.clip(image[..., 0], 0.0, far)) / np.log1p(far)
        grey = (255 * (1.0 - depth)).astype(np.uint8)
        return np.repeat(grey[..., None], 3, axis=2)
    return _PALETTE[np.minimum(image, len(_PALETTE) - 1)]


def _fit(image: np.ndarray, width: int, height: int) -> np.ndarray:
    from PIL import Image  # here, not at import: every env imports this module, few draw frames

    return np.asarray(Image.fromarray(image).resize((max(width, 1), max(height, 1)), Image.Resampling.NEAREST))


def top_down_map(env: Any, size: int, view: float) -> np.ndarray:
    """The map of a `view`-metre window around the ego: scene, route, agents and vehicles (SocialNav), ego."""
    from sim.agents.map_frame import draw_top_down

    machine = env.machine
    x, y, _ = machine.position
    social = getattr(env, "has_agents", False)
    return draw_top_down(
        env.scene,
        (x, y),
        agents=env.crowd.states() if social else None,
        trails=env.crowd.trail if social else None,
        vehicles=env.vehicle_states() if social else None,
        ego=(x, y, machine.yaw, machine.spec.length, machine.spec.width),
        route=env.route.point_at(np.linspace(0.0, env.route.length, 200)),
        size=size,
        view=view,
    )


def hud_text(env: Any) -> str:
    """One line of live metrics: step, speed, route completion, collisions and cost."""
    ep, machine = env.episode, env.machine
    done = min(ep.max_progress / env.route.length, 1.0) if env.route.length > 0 else 0.0
    return (
        f"step {ep.steps}/{ep.horizon}   {3.6 * machine.speed:5.1f} km/h   route {100 * done:3.0f} %   "
        f"cost {ep.cost_total}   {env.spec_machine.name}"
    )


def dashboard(env: Any, width: int, height: int, view: float) -> np.ndarray:
    """Chase camera (left), map around the ego (right), ego-camera panels under the chase view, a metrics line."""
    from sim.frames import camera_image

    bar = 18 if height >= 120 else 0
    body = height - bar
    map_w = min(body, width // 2)
    chase_w = width - map_w
    frame = np.empty((height, width, 3), dtype=np.uint8)
    frame[:] = PANEL_BG
    frame[bar:, :chase_w] = camera_image(env, "chase", chase_w, body)
    frame[bar:, chase_w:] = _fit(top_down_map(env, map_w, view), map_w, body)
    images = getattr(env.observation, "last_images", None) or {}
    if images and body >= 96:
        side = body // 4
        for k, (name, image) in enumerate(images.items()):
            x0 = 4 + k * (side + 4)
            if x0 + side <= chase_w:
                frame[height - side - 4 : height - 4, x0 : x0 + side] = _fit(colourise(name, image), side, side)
    if bar:
        from PIL import Image, ImageDraw

        img = Image.fromarray(frame)
        ImageDraw.Draw(img).text((6, 3), hud_text(env), fill=TEXT)
        frame = np.asarray(img)
    return frame


def render_frame(env: Any) -> np.ndarray | None:
    """`env.render()`: the frame of config.render's camera; in "human" mode it is shown in a window (returns None)."""
    if env.render_mode is None:
        return None
    from sim.frames import camera_image

    render = env.config["render"]
    width, height, camera = int(render["width"]), int(render["height"]), render["camera"]
    if camera == "dashboard":
        frame = dashboard(env, width, height, float(render["top_down_height"]))
    elif camera == "map":
        frame = _fit(top_down_map(env, min(width, height), float(render["top_down_height"]) * 1.6), width, height)
    else:
        frame = camera_image(
            env, camera=camera, width=width, height=height, top_down_height=float(render["top_down_height"])
        )
    if env.render_mode != "human":
        return frame
    window = _WINDOWS.get(env)
    if window is None:
        window = _WINDOWS[env] = HumanWindow(f"curbside {type(env).__name__}", int(env.metadata["render_fps"]))
    window.show(frame)
    return None


def window_of(env: Any) -> HumanWindow | None:
    """The "human" window of `env` (opened by its first render), or None."""
    return _WINDOWS.get(env)


def close_window(env: Any) -> None:
    """Close the env's "human" window, if it has one."""
    window = _WINDOWS.pop(env, None)
    if window is not None:
        window.close()


def human_unavailable() -> str | None:
    """Why render_mode "human" cannot run here (one line with the fix), or None when it can: it needs pygame and a
    display (DISPLAY, WAYLAND_DISPLAY, or SDL_VIDEODRIVER such as dummy)."""
    import importlib.util

    if importlib.util.find_spec("pygame") is None:
        return "render_mode 'human' needs pygame: pip install 'curbside[viewer]'"
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") or os.environ.get("SDL_VIDEODRIVER")):
        return (
            "render_mode 'human' needs a display and DISPLAY is not set; run under a desktop or `xvfb-run`, or "
            "use render_mode 'rgb_array' (RecordVideo, `curbside sim rollout --video`)"
        )
    return None


def served_render_modes(render_mode: str | None) -> list[str]:
    """The render modes this machine serves ("human" only with pygame and a display); a ConfigError, with the fix,
    when `render_mode` is unknown or not served here."""
    if render_mode not in (None, "rgb_array", "human"):
        raise ConfigError(f"unknown render_mode {render_mode!r}; valid: rgb_array, human (or None)")
    human = human_unavailable()
    if render_mode == "human" and human:
        raise ConfigError(human)
    return ["rgb_array"] + ([] if human else ["human"])


class HumanWindow:
    """A pygame window showing RGB frames at most `fps` a second (works under Xvfb or SDL_VIDEODRIVER=dummy)."""

    def __init__(self, title: str, fps: int) -> None:
        reason = human_unavailable()
        if reason:
            raise ConfigError(reason)
        import pygame

        self.pygame = pygame
        pygame.display.init()
        pygame.display.set_caption(title)
        self.screen = None
        self.clock = pygame.time.Clock()
        self.fps = fps
        self.closed = False  # the user closed the window
        self.events: list[Any] = []  # pygame events since the last take_events() (teleop reads keys from them)

    def show(self, frame: np.ndarray) -> None:
        """Draw one frame and handle the window's events."""
        pg = self.pygame
        height, width = frame.shape[:2]
        if self.screen is None or self.screen.get_size() != (width, height):
            self.screen = pg.display.set_mode((width, height))
        pg.surfarray.blit_array(self.screen, np.ascontiguousarray(frame.swapaxes(0, 1)))
        events = pg.event.get()
        self.closed = self.closed or any(event.type == pg.QUIT for event in events)
        self.events.extend(events[-256:])
        del self.events[:-256]  # nobody reading them (plain viewing): keep the latest few
        pg.display.flip()
        self.clock.tick(self.fps)

    def take_events(self) -> list[Any]:
        """The events gathered since the last call."""
        events, self.events = self.events, []
        return events

    def close(self) -> None:
        """Close the window."""
        self.pygame.display.quit()
