"""Viewing: the dashboard frame, render_mode "human" in a pygame window, RecordVideo and `sim rollout --video`."""

from __future__ import annotations

import gymnasium as gym
import imageio.v2 as imageio
import numpy as np
import pytest

from kernel.config import ConfigError
from sim.envs import register_envs
from sim.expert import PurePursuitExpert
from tests.helpers import cli, one_error_line

register_envs()
SHORT = {"route_length": [10.0, 15.0]}


def test_the_dashboard_shows_the_camera_panels_and_metrics() -> None:
    frames = []
    for mods in ([], ["rgb", "depth", "semantic"]):
        env = gym.make(
            "curbside/PointNav-v0", config={**SHORT, "camera": {"modalities": mods}}, render_mode="rgb_array"
        )
        env.reset(seed=2)
        env.step(np.array([0.0, 0.5], dtype=np.float32))
        frames.append(env.render())
        env.close()
    plain, panels = frames
    assert plain.shape == panels.shape == (384, 768, 3) and plain.dtype == np.uint8
    # The bottom-left corner holds the three camera panels only when the camera is on; the top bar the metrics.
    corner = (slice(384 - 100, 384 - 4), slice(4, 3 * 100))
    assert np.abs(plain[corner].astype(int) - panels[corner].astype(int)).mean() > 5
    assert plain[:18].std() > 5  # HUD text on the bar


def test_human_mode_draws_into_a_window_and_closes_it(x_display: str) -> None:
    pytest.importorskip("pygame")
    env = gym.make("curbside/PointNav-v0", config=SHORT, render_mode="human")
    env.reset(seed=0)
    import pygame

    assert pygame.display.get_surface().get_size() == (768, 384)  # reset drew the first frame
    _, _, _, _, _ = env.step(np.array([0.0, 0.5], dtype=np.float32))
    assert env.render() is None
    assert pygame.display.get_surface().get_at((10, 200))[:3] != (0, 0, 0)
    env.close()
    assert not pygame.display.get_init()


def test_human_mode_without_a_display_is_refused_at_make_and_check_env_passes(monkeypatch: pytest.MonkeyPatch) -> None:
    from gymnasium.utils.env_checker import check_env

    for var in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER"):
        monkeypatch.delenv(var, raising=False)
    with pytest.raises(ConfigError, match="xvfb-run"):
        gym.make("curbside/PointNav-v0", config=SHORT, render_mode="human")
    for task in ("PointNav", "SocialNav"):  # no flag: the headless env offers rgb_array only
        env = gym.make(f"curbside/{task}-v0", config=SHORT)
        assert env.unwrapped.metadata["render_modes"] == ["rgb_array"]
        check_env(env.unwrapped)
        env.close()


def test_record_video_writes_the_episode(tmp_path) -> None:
    pytest.importorskip("moviepy")
    env = gym.make("curbside/PointNav-v0", config=SHORT, render_mode="rgb_array")
    env = gym.wrappers.RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda _: True)
    env.reset(seed=0)
    expert, steps = PurePursuitExpert(), 0
    while True:
        _, _, term, trunc, _ = env.step(expert.act(env.unwrapped))
        steps += 1
        if term or trunc:
            break
    env.close()
    (video,) = (tmp_path / "videos").glob("*.mp4")
    reader = imageio.get_reader(video)
    assert reader.count_frames() == steps + 1  # the reset frame, then one a step
    assert reader.get_data(0).shape == (384, 768, 3)


def test_rollout_video_command(tmp_path, capfd: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("moviepy")
    out = tmp_path / "ep.mp4"
    code, stdout, err = cli(["sim", "rollout", "--video", str(out), "--config", '{"route_length": [10, 15]}'], capfd)
    assert code == 0, err
    assert out.stat().st_size > 1000 and "wrote" in stdout
    line = one_error_line(*cli(["sim", "rollout", "--video", str(tmp_path / "ep.gif")], capfd))
    assert "must end in .mp4" in line


def test_the_map_camera_fills_the_configured_frame() -> None:
    env = gym.make(
        "curbside/SocialNav-v0",
        config={**SHORT, "render": {"camera": "map", "width": 200, "height": 120}},
        render_mode="rgb_array",
    )
    env.reset(seed=0)
    assert env.render().shape == (120, 200, 3)
    env.close()
