"""The pipeline's one guard and one rejection row, shared by both drivers (ingest and the DVC stages)."""

from __future__ import annotations

import pytest

from kernel.config import ConfigError
from retrieval.normalize import AssetRejected
from retrieval.pipeline import Rejection, guard, prefiltered, rejected
from retrieval.sources import SourceItem


def _fail(exc: BaseException) -> None:
    raise exc


def test_guard_turns_a_bad_asset_into_a_rejection_and_stops_on_a_bad_config() -> None:
    assert guard("render", lambda x: x + 1, 1) == (2, None)
    assert guard("render", _fail, AssetRejected("degenerate", "empty")) == (
        None,
        Rejection("render", "degenerate", "empty"),
    )
    value, rej = guard("score", _fail, ValueError("x" * 1000))
    assert value is None and rej.stage == "score" and rej.reason == "error"
    assert rej.detail.startswith("ValueError: xxx") and len(rej.detail) == 400
    with pytest.raises(ConfigError):
        guard("normalize", _fail, ConfigError("n_views must be ..."))


def test_rejection_rows_carry_the_content_and_config_hashes() -> None:
    item = SourceItem(
        source="local",
        source_id="a.ply",
        path="",
        license="CC0-1.0",
        metadata={"rejected": ("licence", "CC-BY-NC-4.0")},
    )
    rej = prefiltered(item)
    assert rej == Rejection("fetch", "licence", "CC-BY-NC-4.0")
    res = rejected(item, "0123456789abcdef0123", rej, "cfg")
    assert res.asset is None and res.rejection.detail == "CC-BY-NC-4.0 [sha256:0123456789abcdef]"
    assert (res.rejection.stage, res.rejection.config_hash) == ("fetch", "cfg")
    assert prefiltered(SourceItem(source="local", source_id="b.ply", path="", license="CC0-1.0")) is None
