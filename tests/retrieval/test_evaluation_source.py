"""The evaluation source hides labels from the pipeline and leaves out items that have none to score against."""

from __future__ import annotations

from collections.abc import Iterator

from retrieval.evaluation import _Unlabelled
from retrieval.sources import SourceItem


class _Items:
    name = "fixture"

    def __init__(self, items: list[SourceItem]) -> None:
        self._items = items

    def items(self, limit: int | None = None) -> Iterator[SourceItem]:
        yield from self._items[:limit]


def test_unlabelled_items_are_left_out_and_labels_hidden() -> None:
    items = [
        SourceItem("fixture", "a", "a.glb", name="bench a", category="bench"),
        SourceItem("fixture", "b", "b.glb", name="mystery"),  # no category: nothing to score it against
        SourceItem("fixture", "c", "c.glb", name="fire hydrant c", category="fire_hydrant"),
    ]
    source = _Unlabelled(_Items(items), seed=0)
    out = list(source.items())
    assert [it.source_id for it in out] == ["a", "c"]
    assert all(it.category is None and it.description is None and not it.tags for it in out)
    assert sorted(source.labels.values()) == ["bench", "fire_hydrant"]
    assert [it.name for it in out] != ["bench a", "fire hydrant c"]  # noisy names, not the source's
