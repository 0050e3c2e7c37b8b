"""Where a task's episode scene comes from: a given spec, a JSON file, a dataset folder, or the generator."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from kernel.config import ConfigError
from sim.scene.scene import Scene


def load_scene(config: Mapping[str, Any], seed: int) -> Scene:
    """The scene an episode runs in, parsed once: `scene_spec`, else `scene_path`, else generated with `seed`."""
    if config["scene_spec"] is not None:
        return Scene.parse(dict(config["scene_spec"]), source="config.scene_spec")
    if config["scene_path"] is not None:
        return read_scene(config["scene_path"])
    try:
        from sim.scene import generate_scene
    except ImportError as e:  # the generator is a sibling subsystem; say what to do without it
        raise RuntimeError(
            f"sim.scene.generate_scene is unavailable ({e}); pass config={{'scene_spec': ...}} or 'scene_path'"
        ) from e
    scene_cfg = generator_config(config)
    with warnings.catch_warnings():
        # Without a catalog the generator warns once per category; the env says it once per process instead.
        warnings.filterwarnings("ignore", message="no catalog was given")
        return Scene.parse(generate_scene(scene_cfg, seed, config["catalog"]), source=f"generated scene (seed {seed})")


def generator_config(config: Mapping[str, Any]) -> dict[str, Any]:
    """The scene generator config of generated episodes: `scene` with the split's templates and categories."""
    scene_cfg = dict(config["scene"])
    if config.get("split") is not None:
        from sim.scene.dataset import split_config

        scene_cfg, _ = split_config(config["split"], scene_cfg)
    return scene_cfg


def read_scene(path: str | Path) -> Scene:
    """A scene from a JSON file, with a clear error when it is missing, not JSON or holds bad geometry."""
    return Scene.load(path)


def split_seed_offset(split: str | None) -> int:
    """First generator seed of `split` (0 without a split): splits draw from disjoint seed ranges."""
    if split is None:
        return 0
    from sim.scene.dataset import split_config

    return split_config(split)[1]


def dataset_scenes(scene_dir: str | Path, split: str | None) -> list[Path]:
    """Scene files of `split` in a dataset folder (its index.jsonl), sorted; a clear error when there are none."""
    from sim.scene.dataset import read_index

    root = Path(scene_dir)
    if not root.is_dir():
        raise ConfigError(
            f"config.scene_dir {root} is not a folder; create it with `curbside scenes dataset --out {root}`"
        )
    rows = read_index(root)
    files = sorted(root / row["file"] for row in rows if split is None or row.get("split") == split)
    if not files:
        have = sorted({str(row.get("split")) for row in rows}) or ["none"]
        raise ConfigError(
            f"split {split!r} has no scenes in {root} (it holds: {', '.join(have)}); "
            f"create them with `curbside scenes dataset --split {split} --out {root}`"
        )
    return files
