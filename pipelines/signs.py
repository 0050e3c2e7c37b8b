"""OSM traffic_sign values as human descriptions ("FI:372" -> "a no stopping sign"), never as raw codes.

The table is catalogs/closed_set/traffic_sign_codes.csv (docs/pipelines.md): `sign` is a plain OSM value
("stop") or a country-prefixed code pattern where `x` stands for any digit ("FI:3xx": every three-digit Finnish
sign of group 3). The most specific pattern wins (fewest `x`), so a code the table names exactly gets its own
name, any other code of a known family gets the family's ("a prohibition sign"), and anything else reads
"a traffic sign". `with_value` is used when the sign carries a number ("FI:361[40]", "DE:274-30").
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from pipelines.common import CLOSED_SET_DIR, PipelineError

SIGN_TABLE = CLOSED_SET_DIR / "traffic_sign_codes.csv"
GENERIC = "a traffic sign"
# CC:<digits><letter suffix>, then an optional value in brackets ("[40]", "[left]") or after a dash ("-30").
_CODE = re.compile(r"^(?P<cc>[A-Z]{2}):(?P<num>\d+)[a-z]?(?:\[(?P<br>[^\]]*)\]|-(?P<dash>[\d.]+))?")


@dataclass(frozen=True)
class SignTable:
    """Sign patterns -> descriptions, read from the CSV."""

    rows: tuple[tuple[str, str, str], ...]  # (pattern, description, description with {value})

    def describe(self, value: str) -> str:
        """The description of an OSM traffic_sign value: its first sign (a post often holds several)."""
        first = re.split(r"[;,]", value.strip(), maxsplit=1)[0].strip()
        plain = self._lookup(first.lower())
        if plain is not None:
            return plain[0]
        m = _CODE.match(first)
        if m is None:
            return GENERIC
        code = f"{m['cc']}:{m['num']}"
        best = None
        for pattern, text, with_value in self.rows:
            fits = len(pattern) == len(code) and all(
                p == c or (p == "x" and c.isdigit()) for p, c in zip(pattern, code)
            )
            if fits and (best is None or pattern.count("x") < best[0].count("x")):
                best = (pattern, text, with_value)
        if best is None:
            return GENERIC
        number = m["dash"] or (m["br"] if m["br"] and re.fullmatch(r"\d+(\.\d+)?( ?[a-z]+)?", m["br"]) else None)
        return best[2].format(value=number) if number and best[2] else best[1]

    def _lookup(self, value: str) -> tuple[str, str] | None:
        hit = next((r for r in self.rows if r[0] == value and ":" not in r[0]), None)
        return None if hit is None else (hit[1], hit[2])


def load_sign_table(path: str | Path = SIGN_TABLE) -> SignTable:
    """Read the sign table; a missing column or a description without an article is refused."""
    import pandas as pd

    p = Path(path)
    if not p.exists():
        raise PipelineError(f"traffic sign table {p} not found; restore catalogs/closed_set/traffic_sign_codes.csv")
    df = pd.read_csv(p, dtype=str, keep_default_na=False)
    missing = [c for c in ("sign", "description", "with_value", "provenance") if c not in df.columns]
    if missing:
        raise PipelineError(f"{p} lacks column(s) {', '.join(missing)}")
    for i, r in enumerate(df.itertuples()):
        for text in (r.description, r.with_value):
            if text and not re.match(r"^(a|an) \S", text):
                raise PipelineError(f"{p} row {i + 2}: {text!r} must start with 'a ' or 'an ' (it is a description)")
        if r.with_value and "{value}" not in r.with_value:
            raise PipelineError(f"{p} row {i + 2}: with_value {r.with_value!r} lacks the {{value}} placeholder")
    return SignTable(tuple((r.sign, r.description, r.with_value) for r in df.itertuples()))


@lru_cache(maxsize=1)
def sign_table() -> SignTable:
    """The repository's sign table, read once per process."""
    return load_sign_table()
