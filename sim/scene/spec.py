"""Canonical serialisation of scene specs: rounding, dumps (byte-identical), load (version-checked)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from sim.scene.config import SPEC_VERSION

DECIMALS = 4


def canonical(obj: Any) -> Any:
    """Copy of `obj` with floats rounded to 0.1 mm, tuples as lists and numpy scalars as Python numbers."""
    if isinstance(obj, float):
        r = round(obj, DECIMALS)
        return 0.0 if r == 0 else r  # -0.0 and 0.0 must serialise alike
    if isinstance(obj, bool) or obj is None or isinstance(obj, (int, str)):
        return obj
    if isinstance(obj, dict):
        return {str(k): canonical(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        if len(obj) <= 4 and obj and all(type(v) is float for v in obj):
            # Positions, sizes and bounds: Python rounding beats a numpy round trip on a handful of numbers.
            return [0.0 if (r := round(v, DECIMALS)) == 0 else r for v in obj]
        if obj and isinstance(obj[0], (float, list)):
            # Coordinate arrays dominate specs: round them in one numpy call instead of per element.
            try:
                arr = np.asarray(obj)
            except ValueError:
                arr = None
            if arr is not None and arr.dtype == np.float64:
                return (np.round(arr, DECIMALS) + 0.0).tolist()
        return [canonical(v) for v in obj]
    if hasattr(obj, "tolist"):
        return canonical(obj.tolist())
    raise TypeError(f"cannot serialise {type(obj).__name__} in a scene spec")


def dumps(spec: dict[str, Any]) -> str:
    """Canonical JSON of a spec: sorted keys, no spaces, floats rounded to 4 decimals."""
    return json.dumps(canonical(spec), sort_keys=True, separators=(",", ":"), allow_nan=False)


def save(spec: dict[str, Any], path: str | Path) -> Path:
    """Write the canonical JSON of `spec` to `path` atomically (parents created)."""
    p = Path(path)
    write_atomic(p, dumps(spec))
    return p


TMP_SUFFIX = ".tmp"


def write_atomic(path: str | Path, text: str) -> None:
    """Write `text` to a temporary file beside `path`, fsync it, then os.replace it into place.

    A run killed mid-write leaves the old file or none, never a truncated one (only a `.<name>.<pid>.tmp` file,
    which `sim.scene.dataset.build_dataset` removes on its next run).
    """
    import os

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.parent / f".{p.name}.{os.getpid()}{TMP_SUFFIX}"
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def load(path: str | Path) -> dict[str, Any]:
    """Read a scene spec, refusing a missing file or another spec version."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"no scene spec at {p}; create one with `curbside scenes generate --out {p}`")
    spec = json.loads(p.read_text(encoding="utf-8"))
    version = spec.get("version") if isinstance(spec, dict) else None
    if version != SPEC_VERSION:
        raise ValueError(
            f"{p} is a scene spec of version {version!r}; this curbside reads {SPEC_VERSION!r}: "
            "regenerate it with `curbside scenes generate`"
        )
    return spec
