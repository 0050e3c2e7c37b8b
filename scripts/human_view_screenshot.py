"""Take docs/images/human_view.png: a SocialNav episode in the render_mode="human" window on an X display
(run it under Xvfb: `xvfb-run -s "-screen 0 1024x768x24" python scripts/human_view_screenshot.py`), grabbed from
the X server after 60 expert steps."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import gymnasium as gym
from PIL import ImageGrab

from sim.envs import register_envs
from sim.expert import PurePursuitExpert
from sim.viewer import window_of


def main(out: str = "docs/images/human_view.png", steps: int = 45, seed: int = 5) -> None:
    """Drive the expert for `steps` steps in the human window and save a grab of the window's screen area."""
    if not os.environ.get("DISPLAY"):
        sys.exit("no DISPLAY: run under xvfb-run (see this file's docstring)")
    os.environ["SDL_VIDEO_WINDOW_POS"] = "0,0"  # SDL centres new windows; the grab reads the screen's corner
    register_envs()
    cfg = {"camera": {"modalities": ["rgb", "depth", "semantic"]}, "route_length": [40.0, 60.0]}
    env = gym.make("curbside/SocialNav-v0", config=cfg, render_mode="human")
    env.reset(seed=seed)
    expert = PurePursuitExpert()
    for _ in range(steps):
        _, _, term, trunc, _ = env.step(expert.act(env.unwrapped))
        if term or trunc:
            break
    window = window_of(env.unwrapped)
    w, h = window.screen.get_size()
    # What the X server shows, not pygame's buffer.
    shot = ImageGrab.grab(bbox=(0, 0, w, h), xdisplay=os.environ["DISPLAY"])
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    shot.save(out)
    env.close()
    print(f"wrote {out} ({w}x{h})")


if __name__ == "__main__":
    main(*sys.argv[1:2])
