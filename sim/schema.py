"""Declarative value checks for strict configs (MetaDrive style): one (key -> type, range) table per config.

`kernel.config.merge_strict` rejects unknown keys; the tables here reject bad values of known keys (wrong
type, NaN/inf, out of range) at construction, with the valid range in the message, so a bad number fails
where it is given instead of turning into NaN observations or an IndexError many steps later.

A table maps each key to a `Rule` or to a nested table (a sub-config such as `lidar`). Keys a table does not
list are checked against the type of their default value when defaults are given (so a key another module
adds to its defaults is still type- and finiteness-checked).

Each config is declared once, beside the component that reads it, as a mapping of `Key`s (default, rule and
one-line doc together; a sub-config is a nested mapping of Keys): `defaults_of` and `table_of` derive its
defaults dict and its table, and `key_field` / `dataclass_keys` declare the Keys of a dataclass's fields.
"""

from __future__ import annotations

import copy
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any, Union

from kernel.config import ConfigError, excerpt


def _num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _fmt(x: float) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


@dataclass(frozen=True)
class Rule:
    """One key's valid values: its kind, numeric bounds, choices, and whether None is allowed."""

    kind: str  # int | float | bool | str | choice | pair | list | mapping | path | file | codes | any
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False  # lo itself is not allowed
    hi_open: bool = False
    choices: tuple[Any, ...] = ()  # choice: the valid values; codes: the valid letters; list: valid items
    none: bool = False  # None is valid too
    item: Rule | None = None  # pair: the rule of both elements; list: the rule of every item
    max_len: int | None = None  # codes / list: longest allowed
    hint: str = ""  # appended to the message (what the value means, how to fix it)

    def describe(self) -> str:
        """The valid values in words, e.g. 'a finite number in (0, 1]'."""
        k = self.kind
        if k in ("int", "float"):
            what = "an integer" if k == "int" else "a finite number"
            if self.lo is not None and self.hi is not None:
                what += (
                    f" in {'(' if self.lo_open else '['}{_fmt(self.lo)}, {_fmt(self.hi)}{')' if self.hi_open else ']'}"
                )
            elif self.lo is not None:
                what += f" {'>' if self.lo_open else '>='} {_fmt(self.lo)}"
            elif self.hi is not None:
                what += f" {'<' if self.hi_open else '<='} {_fmt(self.hi)}"
        elif k == "bool":
            what = "true or false"
        elif k == "str":
            what = "a string"
        elif k == "choice":
            what = "one of " + ", ".join(map(str, self.choices))
        elif k == "pair":
            what = f"a [min, max] pair with min <= max, each {self.item.describe() if self.item else 'a number'}"
        elif k == "list":
            what = "a list" + (
                f" of {', '.join(map(str, self.choices))}"
                if self.choices
                else f" of {self.item.describe()}"
                if self.item
                else ""
            )
        elif k == "mapping":
            what = "a JSON object (dict)" + (f" of {self.item.describe()}" if self.item else "")
        elif k == "path":
            what = "a path (string)"
        elif k == "file":
            what = "the path of an existing file"
        elif k == "codes":
            what = f"a string of the letters {''.join(self.choices)}"
            if self.max_len:
                what += f" (at most {self.max_len})"
        else:
            what = "any value"
        return what + (" or null" if self.none else "")

    def ok(self, v: Any) -> bool:
        """Whether `v` satisfies this rule."""
        if v is None:
            return self.none or self.kind == "any"
        k = self.kind
        if k in ("int", "float"):
            if not _num(v) or (k == "int" and not isinstance(v, int)) or not math.isfinite(v):
                return False
            if self.lo is not None and (v < self.lo or (self.lo_open and v == self.lo)):
                return False
            if self.hi is not None and (v > self.hi or (self.hi_open and v == self.hi)):
                return False
            return True
        if k == "bool":
            return isinstance(v, bool)
        if k == "str":
            return isinstance(v, str)
        if k == "choice":  # true / false only where a bool is a choice (1 is not True here)
            if isinstance(v, bool):
                return any(c is v for c in self.choices)
            return isinstance(v, (str, int, float)) and any(c == v and not isinstance(c, bool) for c in self.choices)
        if k == "pair":
            item = self.item or Rule("float")
            return isinstance(v, (list, tuple)) and len(v) == 2 and all(item.ok(x) for x in v) and v[0] <= v[1]
        if k == "list":
            if not isinstance(v, (list, tuple)) or (self.max_len is not None and len(v) > self.max_len):
                return False
            if self.choices:
                return all(isinstance(x, str) and x in self.choices for x in v)
            return all(self.item.ok(x) for x in v) if self.item else True
        if k == "mapping":
            return isinstance(v, Mapping) and (self.item is None or all(self.item.ok(x) for x in v.values()))
        if k == "path":
            return isinstance(v, (str, os.PathLike)) and str(v) != ""
        if k == "file":
            return isinstance(v, (str, os.PathLike)) and str(v) != "" and os.path.isfile(v)
        if k == "codes":
            return (
                isinstance(v, str)
                and 0 < len(v) <= (self.max_len or len(v))
                and all(c in self.choices for c in v.upper())
            )
        return True

    def check(self, v: Any, name: str) -> None:
        """Raise ConfigError naming `name`, the valid values and the value given unless `v` is valid."""
        if not self.ok(v):
            hint = f" ({self.hint})" if self.hint else ""
            if self.kind == "choice":  # the style of kernel.config.check_choice
                listing = ", ".join(map(str, self.choices)) + (" (or null)" if self.none else "")
                raise ConfigError(f"unknown {name} {excerpt(v)}; valid: {listing}{hint}")
            raise ConfigError(f"{name} must be {self.describe()}, got {excerpt(v)}{hint}")


def Int(lo: int | None = None, hi: int | None = None, *, none: bool = False, hint: str = "") -> Rule:
    """An integer (not a bool) in [lo, hi]."""
    return Rule("int", lo, hi, none=none, hint=hint)


def Float(
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    none: bool = False,
    hint: str = "",
) -> Rule:
    """A finite int or float in the range (open ends with lo_open / hi_open)."""
    return Rule("float", lo, hi, lo_open=lo_open, hi_open=hi_open, none=none, hint=hint)


def Pos(hi: float, *, none: bool = False, hint: str = "") -> Rule:
    """A finite number in (0, hi]."""
    return Float(0.0, hi, lo_open=True, none=none, hint=hint)


def Bool() -> Rule:
    """true or false."""
    return Rule("bool")


def Choice(*choices: Any, none: bool = False) -> Rule:
    """One of the given values."""
    return Rule("choice", choices=tuple(choices), none=none)


def Pair(item: Rule, *, hint: str = "") -> Rule:
    """A [min, max] pair with min <= max, both satisfying `item`."""
    return Rule("pair", item=item, hint=hint)


Table = Mapping[str, Union[Rule, "Table"]]


def infer(default: Any) -> Rule:
    """The rule of a key no table lists, from its default value's type."""
    if isinstance(default, bool):
        return Bool()
    if isinstance(default, int):
        return Int()
    if isinstance(default, float):
        return Float()
    if isinstance(default, str):
        return Rule("str")
    if isinstance(default, Mapping):
        return Rule("mapping")
    if isinstance(default, (list, tuple)):
        if len(default) == 2 and all(_num(x) for x in default):
            return Pair(Float())
        return Rule("list")
    return Rule("any")


def check_table(
    cfg: Mapping[str, Any], table: Table, *, name: str = "config", defaults: Mapping[str, Any] | None = None
) -> None:
    """Check every key of `cfg` against `table` (nested tables for sub-configs); ConfigError on the first bad one."""
    for key, value in cfg.items():
        rule = table.get(key)
        sub_defaults = defaults.get(key) if isinstance(defaults, Mapping) else None
        full = f"{name}.{key}"
        if isinstance(rule, Mapping):
            if not isinstance(value, Mapping):
                raise ConfigError(
                    f"{full} must be a JSON object (dict) of {', '.join(sorted(rule))}, got {excerpt(value)}"
                )
            check_table(value, rule, name=full, defaults=sub_defaults if isinstance(sub_defaults, Mapping) else None)
            continue
        if rule is None:
            if defaults is None or key not in defaults:
                continue  # merge_strict already rejected keys without a default
            rule = infer(defaults[key])
        rule.check(value, full)


@dataclass(frozen=True)
class Key:
    """One config key, declared once: its default value, the rule its values obey and a one-line doc.

    `rule` is a Table (not a Rule) for a key whose value is a partial sub-config, such as PointNav's `reward`
    (overrides of a preset's terms, default {}).
    """

    default: Any
    rule: Rule | Table
    doc: str


# A config's declaration: each key's Key, or a nested mapping of Keys for a sub-config (such as `lidar`).
Keys = Mapping[str, Union[Key, "Keys"]]


def defaults_of(keys: Keys) -> dict[str, Any]:
    """The defaults dict of a declaration, in declaration order; mutable defaults are deep copies."""
    return {
        name: copy.deepcopy(key.default) if isinstance(key, Key) else defaults_of(key) for name, key in keys.items()
    }


def table_of(keys: Keys) -> dict[str, Rule | Table]:
    """The table (key -> Rule, or nested table) of a declaration, for `check_table`."""
    return {name: key.rule if isinstance(key, Key) else table_of(key) for name, key in keys.items()}


def redeclare(key: Key | Keys, **changes: Any) -> Key:
    """`key` with some of its default, rule and doc replaced: an inherited key that another config declares anew
    (SocialNav's cost_kinds); TypeError for a sub-config."""
    if not isinstance(key, Key):
        raise TypeError(f"redeclare takes a Key, not a sub-config ({', '.join(key)})")
    return replace(key, **changes)


def key_field(default: Any, rule: Rule, doc: str) -> Any:
    """A dataclass field whose default, rule and doc are one Key (`dataclass_keys` collects them)."""
    return field(default=default, metadata={"key": Key(default, rule, doc)})


def dataclass_keys(cls: type[Any]) -> dict[str, Key]:
    """The Keys of a dataclass's fields declared with `key_field`, in field order."""
    return {f.name: f.metadata["key"] for f in fields(cls) if "key" in f.metadata}
