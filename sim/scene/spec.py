"""Canonical serialisation of scene specs: rounding, dumps (byte-identical), load (version-checked)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import orjson

DECIMALS = 4
_SCALE = 10.0**DECIMALS
assert _SCALE == 10000.0  # the scale the plain-float rounding paths below multiply by (literal there for speed)


def _round(v: float) -> float:
    """round(v, 4), with 0.0 for -0.0, for a Python float; mostly without Python's decimal round trip.

    With |v * 1e4| < 1e12 the product is off the exact one by < 2 ** -13, so a fraction within 0.499 of an
    integer r means the exact value rounds to r too (no tie): round(v, 4) is then the double nearest to
    r / 10 ** 4, which is what the (correctly rounded) division r / 10000.0 gives. Other values (near a tie,
    huge, inf, nan) take round(v, 4) itself.
    """
    y = v * 10000.0
    if -1e12 < y < 1e12:
        r = round(y)
        d = y - r
        if -0.499 < d < 0.499:
            return r / 10000.0  # an int 0 gives 0.0, never -0.0
    return _round_slow(v)


def _round_slow(v: float) -> float:
    if not math.isfinite(v):
        raise ValueError(f"scene specs hold finite numbers only, got {v!r}")
    r = round(v, DECIMALS)
    return 0.0 if r == 0 else r  # -0.0 and 0.0 must serialise alike


round_value = _round  # a float as `canonical` stores it (0.1 mm, never -0.0), for code that builds specs


def round_array(v: np.ndarray, *, rows: bool = False) -> list[Any]:
    """A float array as `canonical` stores it, as (nested) Python float lists: every element as `round_value`
    rounds it, or with `rows` as `round_points` rounds coordinate rows (ties left to rint)."""
    y = np.asarray(v, dtype=np.float64) * 10000.0
    r = np.rint(y)  # round half to even, as Python's round(y)
    out = r / 10000.0 + 0.0  # + 0.0 turns -0.0 into 0.0, as the int round(y) does
    if rows:
        if not np.isfinite(y).all():
            raise ValueError("scene specs hold finite numbers only, got a coordinate list with inf or nan")
        return out.tolist()
    slow = ~(np.abs(y - r) < 0.499)  # near a tie, huge or not finite: round(v, 4) decides (and raises on nan)
    if slow.any():
        flat, vals = out.reshape(-1), np.asarray(v, dtype=np.float64).reshape(-1)
        for i in np.flatnonzero(slow.reshape(-1)).tolist():
            flat[i] = _round_slow(float(vals[i]))
    return out.tolist()


def round_points(rows: list[list[float]]) -> list[list[float]]:
    """[x, y] rows of Python floats as `canonical` stores them (what `_float_rows` returns for them)."""
    return [[round(x * _SCALE) / _SCALE, round(y * _SCALE) / _SCALE] for x, y in rows]


def canonical(obj: Any) -> Any:
    """Copy of `obj` with floats rounded to 0.1 mm, tuples as lists and numpy scalars as Python numbers."""
    # Fast paths for the exact built-in types specs are made of (the objects list holds thousands of small
    # dicts and coordinate lists); anything else goes through `_canonical`, which defines the result.
    kind = type(obj)
    if kind is float:
        return _round(obj)
    if kind is str or kind is int or obj is None or kind is bool:
        return obj
    if kind is dict:
        out = {}
        for k, v in obj.items():
            if type(k) is not str:
                k = str(k)
            tv = type(v)
            if tv is str or tv is int or v is None or tv is bool:
                out[k] = v
            elif tv is float:
                out[k] = _round(v)
            else:
                out[k] = canonical(v)
        return out
    if kind is list:
        n_items = len(obj)
        if 0 < n_items <= 32:  # longer coordinate lists are quicker in numpy (`_canonical`)
            t0 = type(obj[0])
            r: list[float] | list[list[float]] | None
            if t0 is float:
                for v in obj:
                    if type(v) is not float:
                        return _canonical(obj)
                if n_items <= 4:
                    return [_round(v) for v in obj]
                r = _np_rounded(obj)
            elif t0 is list:
                r = _float_rows(obj)
            else:
                r = None
            if r is not None:
                return r
    return _canonical(obj)


def _np_rounded(obj: list[float]) -> list[float] | None:
    """(np.round(np.asarray(obj), 4) + 0.0).tolist() for a list of Python floats, in plain Python: numpy
    multiplies by 10.0 ** 4, rounds half to even (rint, as Python's round) and divides back; the quotient of
    the int is the same double and never -0.0. None for inf or nan (left to numpy and json, as before)."""
    try:
        return [round(v * 10000.0) / 10000.0 for v in obj]
    except (OverflowError, ValueError):
        return None


def _float_rows(obj: list[Any]) -> list[list[float]] | None:
    """Equal-length lists of Python floats (a float64 array in `_canonical`), rounded as numpy rounds them
    (see `_np_rounded`). None when `obj` is anything else."""
    n = len(obj[0])
    if n == 0:
        return None
    out = []
    try:
        if n == 2:
            for row in obj:
                if type(row) is not list or len(row) != 2:
                    return None
                x, y = row
                if type(x) is not float or type(y) is not float:
                    return None
                out.append([round(x * 10000.0) / 10000.0, round(y * 10000.0) / 10000.0])
            return out
        for row in obj:
            if type(row) is not list or len(row) != n:
                return None
            for v in row:
                if type(v) is not float:
                    return None
            out.append([round(v * 10000.0) / 10000.0 for v in row])
    except (OverflowError, ValueError):
        return None  # inf or nan: left to numpy and json, as before
    return out


def _canonical(obj: Any) -> Any:
    if isinstance(obj, float):
        return _round_slow(float(obj))
    if isinstance(obj, bool) or obj is None or isinstance(obj, (int, str)):
        return obj
    if isinstance(obj, dict):
        return {str(k): canonical(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        if len(obj) <= 4 and obj and all(type(v) is float for v in obj):
            # Positions, sizes and bounds: Python rounding beats a numpy round trip on a handful of numbers.
            return [_round_slow(v) for v in obj]
        if obj and isinstance(obj[0], (float, list)):
            # Coordinate arrays dominate specs: round them in one numpy call instead of per element.
            try:
                arr = np.asarray(obj)
            except ValueError:
                arr = None
            if arr is not None and arr.dtype == np.float64:
                if not np.isfinite(arr).all():
                    raise ValueError("scene specs hold finite numbers only, got a coordinate list with inf or nan")
                return (np.round(arr, DECIMALS) + 0.0).tolist()
        return [canonical(v) for v in obj]
    if hasattr(obj, "tolist"):
        return canonical(obj.tolist())
    raise TypeError(f"cannot serialise {type(obj).__name__} in a scene spec")


def dumps(spec: dict[str, Any]) -> str:
    """Canonical JSON of a spec: sorted keys, no spaces, floats rounded to 4 decimals."""
    return encode(canonical(spec))


def encode(spec: dict[str, Any]) -> str:
    """JSON text of a spec that is canonical already (as `generate_scene` returns it): sorted keys, no spaces.

    orjson writes the same bytes as `json.dumps(spec, sort_keys=True, separators=(",", ":"))` for ASCII text,
    64-bit integers and finite floats (both print a float's shortest round-trip digits), about 6x faster.
    Anything else (non-ASCII text, which json escapes as \\u, or a huge integer) goes through json itself, so a
    spec's bytes never depend on which encoder wrote them. `canonical` has already refused inf and nan.
    """
    try:
        text = orjson.dumps(spec, option=orjson.OPT_SORT_KEYS).decode("utf-8")
    except TypeError:  # an integer beyond 64 bits
        text = ""
    if not text or not text.isascii():
        text = json.dumps(spec, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return text


def save(spec: dict[str, Any], path: str | Path, *, is_canonical: bool = False, durable: bool = True) -> Path:
    """Write the canonical JSON of `spec` to `path` atomically (parents created).

    `is_canonical=True` skips rounding a spec that `generate_scene` returned (its floats are rounded already);
    `durable=False` skips the fsync (see `write_atomic`).
    """
    file_path = Path(path)
    write_atomic(file_path, encode(spec) if is_canonical else dumps(spec), durable=durable)
    return file_path


TMP_SUFFIX = ".tmp"


def write_atomic(path: str | Path, text: str, *, durable: bool = True) -> None:
    """Write `text` to a temporary file beside `path`, fsync it, then os.replace it into place.

    A run killed mid-write leaves the old file or none, never a truncated one (only a `.<name>.<pid>.tmp` file,
    which `sim.scene.dataset.build_dataset` removes on its next run). `durable=False` skips the fsync, which only
    guards against a power loss or OS crash (the file could then come back empty): for callers that verify every
    file when they resume, as the dataset builder does, at ~4 ms a file saved.
    """
    import os

    file_path = Path(path)
    file_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = file_path.parent / f".{file_path.name}.{os.getpid()}{TMP_SUFFIX}"
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
            if durable:
                fh.flush()
                os.fsync(fh.fileno())
        os.replace(tmp, file_path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def load(path: str | Path) -> dict[str, Any]:
    """Read a scene spec JSON file as a dict, checked by `Scene.load` (version, fields, finiteness)."""
    from sim.scene.scene import Scene

    return Scene.load(path).spec  # type: ignore[return-value]
