"""Strict configuration dictionaries in the style of MetaDrive: unknown keys raise, listing the valid ones."""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any


class ConfigError(ValueError):
    """A configuration that names an unknown key or holds an invalid value."""


def merge_strict(
    defaults: Mapping[str, Any], overrides: Mapping[str, Any] | None, *, name: str = "config"
) -> dict[str, Any]:
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


def excerpt(value: Any, limit: int = 80) -> str:
    """`repr(value)` cut to `limit` characters: error lines quote what they refuse, never a whole document."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text) - limit} more characters)"


YAML_MAX_BYTES = 10_000_000  # a config or scene file; larger is not one


def load_yaml(text: str, what: str) -> Any:
    """Parse YAML text of a config file (`what` names it in errors) without aliases: `*name` references can expand a
    few hundred bytes into gigabytes, and no config here needs them. ConfigError for anything unparsable."""
    import yaml

    class NoAliasLoader(yaml.SafeLoader):
        def compose_node(self, parent: Any, index: Any) -> Any:
            if self.check_event(yaml.AliasEvent):
                event = self.peek_event()
                raise ConfigError(
                    f"{what}: YAML alias *{event.anchor} at line {event.start_mark.line + 1}; aliases "
                    "are not accepted in config files, write the value out"
                )
            return super().compose_node(parent, index)

    if len(text) > YAML_MAX_BYTES:
        raise ConfigError(f"{what} holds {len(text):,} characters, more than a config file's {YAML_MAX_BYTES:,}")
    try:
        return yaml.load(text, Loader=NoAliasLoader)  # noqa: S506 (a SafeLoader subclass)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        raise ConfigError(f"{what} is not valid YAML{where}: {getattr(e, 'problem', None) or e}") from None
