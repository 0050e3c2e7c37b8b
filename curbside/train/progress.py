"""One rich progress bar for long training work (demonstrations, gradient steps)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager


@contextmanager
def progress_bar(description: str, total: int, enabled: bool = True) -> Iterator[Callable[[int], None]]:
    """A transient rich bar; yields `update(completed)` (a no-op when disabled)."""
    if not enabled:
        yield lambda completed: None
        return
    from rich.progress import Progress

    bar = Progress(transient=True)
    job = bar.add_task(description, total=total)
    with bar:
        yield lambda completed: bar.update(job, completed=min(completed, total))
