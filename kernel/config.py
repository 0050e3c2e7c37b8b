"""Strict configuration dictionaries in the style of MetaDrive: unknown keys raise, listing the valid ones."""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any


class ConfigError(ValueError):
    """A configuration that names an unknown key or holds an invalid value."""


def merge_strict(defaults: Mapping[str, Any], overrides: Mapping[str, Any] | None, *, name: str = "config") -> dict[str, Any]:
    """Return a deep copy of `defaults` updated by `overrides`, rejecting keys `defaults` does not have."""
    merged = copy.deepcopy(dict(defaults))
    if not overrides:
        return merged
    if not isinstance(overrides, Mapping):
        raise ConfigError(f"{name} must be a mapping, got {type(overrides).__name__}")
    for key, value in overrides.items():
        if key not in merged:
            valid = ", ".join(sorted(merged))
            raise ConfigError(f"unknown key {key!r} in {name}; valid keys: {valid}")
        # Nested dicts are merged key by key so a partial override keeps the other defaults.
        if isinstance(merged[key], dict) and merged[key] and isinstance(value, Mapping):
            merged[key] = merge_strict(merged[key], value, name=f"{name}.{key}")
        else:
            merged[key] = copy.deepcopy(value)
    return merged


def check_choice(value: Any, valid: list[str] | tuple[str, ...], *, what: str) -> None:
    """Raise ConfigError naming `what` and the valid choices when `value` is not one of them."""
    if value not in valid:
        raise ConfigError(f"unknown {what} {value!r}; valid: {', '.join(map(str, valid))}")
