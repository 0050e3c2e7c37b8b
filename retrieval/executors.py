"""Executors that map the per-asset stage function over items: `local` (in-process), `process`, `ray`.

All three yield results in input order, so the caller writes the catalog identically whichever runs the work.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any

from curbside.config import check_choice

EXECUTORS = ("local", "process", "ray")


def run_map(fn: Callable[..., Any], items: Iterable[Any], *, executor: str = "local", workers: int | None = None,
            address: str | None = None, args: tuple = ()) -> Iterator[Any]:
    """Yield fn(item, *args) for each item, in order, computed by the chosen executor."""
    check_choice(executor, EXECUTORS, what="executor")
    if executor == "local":
        for item in items:
            yield fn(item, *args)
    elif executor == "process":
        yield from _process_map(fn, items, workers, args)
    else:
        yield from _ray_map(fn, items, workers, address, args)


def _process_map(fn: Callable[..., Any], items: Iterable[Any], workers: int | None, args: tuple) -> Iterator[Any]:
    import multiprocessing as mp
    import os
    from collections import deque
    from concurrent.futures import ProcessPoolExecutor

    workers = workers or os.cpu_count() or 1
    # spawn: torch and pybullet state must not be forked from a parent that already loaded them.
    with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn")) as pool:
        window: deque = deque()
        for item in items:
            window.append(pool.submit(fn, item, *args))
            if len(window) >= 2 * workers:
                yield window.popleft().result()
        while window:
            yield window.popleft().result()


def _ray_map(fn: Callable[..., Any], items: Iterable[Any], workers: int | None, address: str | None,
             args: tuple) -> Iterator[Any]:
    from collections import deque

    try:
        import ray
    except ImportError as exc:
        raise ImportError("the ray executor needs `pip install ray`") from exc
    started = False
    if not ray.is_initialized():
        if address:
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        started = True
    try:
        remote = ray.remote(num_cpus=1)(fn)
        shared = [ray.put(a) for a in args]
        capacity = max(2, 2 * int(ray.cluster_resources().get("CPU", 1)))
        window: deque = deque()
        for item in items:
            window.append(remote.remote(item, *shared))
            if len(window) >= capacity:
                yield ray.get(window.popleft())
        while window:
            yield ray.get(window.popleft())
    finally:
        if started:
            ray.shutdown()
