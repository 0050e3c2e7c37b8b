"""Teleoperation: drive a task from the keyboard or any pygame joystick (gamepad, racing wheel) in the env's
"human" window (the dashboard with live metrics), and record the episodes as a Minari dataset in the format of
`curbside demos collect` (so `curbside train --demos` and `load_demos` read them the same way).

Keys: arrows or WASD drive (up throttle, down brake, left/right steer), R ends the episode, Esc or Q stops.
Joysticks: axes mapped by a small config (`DEVICE_PRESETS`, or a JSON file of the same keys); button 0 ends the
episode, button 1 stops.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from curbside.train.demos import EpisodeRecorder, write_dataset
from curbside.train.envs import env_id
from kernel.config import ConfigError, merge_strict

if TYPE_CHECKING:
    from sim.envs.pointnav import PointNavEnv

# Axis maps. Pedals rest at +1 and read -1 pressed on most wheels (`pedals`); stick y is -1 pushed forward.
DEVICE_PRESETS: dict[str, dict[str, Any]] = {
    "gamepad": {
        "steer_axis": 0,
        "throttle_axis": 1,
        "brake_axis": None,
        "invert_steer": True,
        "invert_throttle": True,
        "pedals": False,
        "deadzone": 0.08,
        "end_button": 0,
        "quit_button": 1,
    },
    "wheel": {
        "steer_axis": 0,
        "throttle_axis": 2,
        "brake_axis": 3,
        "invert_steer": True,
        "invert_throttle": False,
        "pedals": True,
        "deadzone": 0.02,
        "end_button": 0,
        "quit_button": 1,
    },
}
DEVICES = ("keyboard", *DEVICE_PRESETS)
STEER_RATE = 3.0  # keyboard steering slews at this many full-scale units a second, as a hand turns a wheel


class Controls:
    """What a device says each step: the action, and whether the user ended the episode or stopped."""

    def __init__(self) -> None:
        self.end_episode = False
        self.stop = False

    def action(self, events: list[Any], dt: float) -> np.ndarray:
        """The [steering, throttle_brake] action after `events` (pygame events since the last step)."""
        raise NotImplementedError


class KeyboardControls(Controls):
    """Arrows or WASD, with steering that slews (a tap steers a little, holding steers fully)."""

    def __init__(self) -> None:
        super().__init__()
        import pygame as pg

        self.pg = pg
        self.held: set[int] = set()
        self.steer = 0.0
        self.left, self.right = {pg.K_LEFT, pg.K_a}, {pg.K_RIGHT, pg.K_d}
        self.up, self.down = {pg.K_UP, pg.K_w}, {pg.K_DOWN, pg.K_s}

    def action(self, events: list[Any], dt: float) -> np.ndarray:
        """Update the held keys from the events and read the action from them."""
        pg = self.pg
        for e in events:
            if e.type == pg.KEYDOWN:
                self.held.add(e.key)
                self.end_episode |= e.key == pg.K_r
                self.stop |= e.key in (pg.K_ESCAPE, pg.K_q)
            elif e.type == pg.KEYUP:
                self.held.discard(e.key)
        target = float(bool(self.held & self.left)) - float(bool(self.held & self.right))
        step = STEER_RATE * dt
        self.steer += min(max(target - self.steer, -step), step)
        throttle = float(bool(self.held & self.up)) - float(bool(self.held & self.down))
        return np.array([self.steer, throttle], dtype=np.float32)


def axes_action(axes: list[float], mapping: Mapping[str, Any]) -> np.ndarray:
    """[steering, throttle_brake] from joystick axis values under an axis map (deadzone, inversion, pedals)."""

    def axis(i: int | None) -> float:
        if i is None or i >= len(axes):
            return 0.0
        v = float(axes[i])
        return 0.0 if abs(v) < float(mapping["deadzone"]) else v

    steer = -axis(mapping["steer_axis"]) if mapping["invert_steer"] else axis(mapping["steer_axis"])
    if mapping["pedals"]:
        pedal = lambda i: 0.0 if i is None or i >= len(axes) else (1.0 - float(axes[i])) / 2.0  # noqa: E731
        throttle = pedal(mapping["throttle_axis"]) - pedal(mapping["brake_axis"])
    else:
        t = axis(mapping["throttle_axis"])
        throttle = -t if mapping["invert_throttle"] else t
        throttle -= axis(mapping["brake_axis"]) if mapping["brake_axis"] is not None else 0.0
    return np.clip(np.array([steer, throttle], dtype=np.float32), -1.0, 1.0)


class JoystickControls(Controls):
    """The first pygame joystick (gamepad, racing wheel, flight stick), its axes read through `mapping`."""

    def __init__(self, mapping: Mapping[str, Any]) -> None:
        super().__init__()
        import pygame as pg

        pg.joystick.init()
        if pg.joystick.get_count() == 0:
            raise ConfigError("no joystick, gamepad or wheel is connected; plug one in or use --device keyboard")
        self.pg, self.mapping = pg, mapping
        self.stick = pg.joystick.Joystick(0)

    def action(self, events: list[Any], dt: float) -> np.ndarray:
        """Read the axes now; buttons from the events."""
        for e in events:
            if e.type == self.pg.JOYBUTTONDOWN:
                self.end_episode |= e.button == self.mapping["end_button"]
                self.stop |= e.button == self.mapping["quit_button"]
            self.stop |= e.type == self.pg.KEYDOWN and e.key in (self.pg.K_ESCAPE, self.pg.K_q)
        return axes_action([self.stick.get_axis(i) for i in range(self.stick.get_numaxes())], self.mapping)


def device_mapping(device: str, mapping_file: Path | None = None) -> dict[str, Any]:
    """The axis map of a joystick device: its preset, with a JSON file's keys over it (unknown keys rejected)."""
    if device not in DEVICE_PRESETS:
        raise ConfigError(f"unknown device {device!r}; valid: {', '.join(DEVICES)}")
    try:
        extra = json.loads(Path(mapping_file).read_text()) if mapping_file is not None else {}
    except json.JSONDecodeError as e:
        raise ConfigError(
            f"--mapping {mapping_file} is not JSON ({e}); write an object such as "
            '{"steer_axis": 0, "throttle_axis": 2}'
        ) from None
    if not isinstance(extra, dict):
        raise ConfigError(f"--mapping {mapping_file} must hold a JSON object of axis settings")
    return merge_strict(DEVICE_PRESETS[device], extra, name=f"--mapping {mapping_file}")


def teleop(
    task: str,
    out: Path,
    *,
    device: str = "keyboard",
    mapping_file: Path | None = None,
    env_config: Mapping[str, Any] | None = None,
    episodes: int | None = None,
    max_steps: int | None = None,
    seed: int = 0,
    before_step: Callable[[int], None] | None = None,
) -> dict[str, Any]:
    """Drive `task` by hand until `episodes` end, `max_steps` pass or the user stops; write what was driven as
    the Minari dataset curbside/<task>-teleop-v0 under `out` and return its summary. `before_step(k)` runs
    before step k (scripted input in tests)."""
    import gymnasium as gym

    from sim.envs import register_envs
    from sim.viewer import window_of

    if device not in DEVICES:
        raise ConfigError(f"unknown device {device!r}; valid: {', '.join(DEVICES)}")
    register_envs()
    env = gym.make(env_id(task), config=dict(env_config or {}), render_mode="human")
    u = cast("PointNavEnv", env.unwrapped)  # every task's env is a PointNavEnv (SocialNavEnv extends it)
    recorded: list[Any] = []
    successes, total = 0, 0
    try:
        obs, _ = env.reset(seed=seed)  # opens the window: pygame is up for the devices
        controls = (
            KeyboardControls() if device == "keyboard" else JoystickControls(device_mapping(device, mapping_file))
        )
        window = window_of(u)
        assert window is not None  # reset in "human" mode rendered, which opened it
        episode = EpisodeRecorder(obs, seed)
        while True:
            if before_step is not None:
                before_step(total)
            a = controls.action(window.take_events(), u.dt)
            obs, r, term, trunc, info = env.step(a)
            total += 1
            user_end = controls.end_episode or controls.stop or window.closed or total == max_steps
            episode.add(a, obs, r, term, trunc or (user_end and not term))
            if term or trunc or user_end:
                successes += int(bool(info.get("is_success", False)))
                recorded.append(episode.buffer(len(recorded)))
                controls.end_episode = False
                if controls.stop or window.closed or total == max_steps or len(recorded) == episodes:
                    break
                obs, _ = env.reset(seed=seed + len(recorded))
                episode = EpisodeRecorder(obs, seed + len(recorded))
        meta = {"steps": total, "success_rate": successes / max(len(recorded), 1), "task": task, "device": device}
        return write_dataset(
            recorded,
            env,
            out,
            f"curbside/{task.lower()}-teleop-v0",
            algorithm=f"teleop({device})",
            meta=meta,
            description=f"{task} episodes driven by a person with `curbside sim teleop` ({device}).",
        )
    finally:
        env.close()
