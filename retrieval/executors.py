"""Executors that map the per-asset stage function over items: `local` (in-process), `process`, `ray`.

All three yield results in input order, so the caller writes the catalog identically whichever runs the work.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any

from curbside.config import check_choice

EXECUTORS = ("local", "process", "ray")
PR_SET_PDEATHSIG = 1  # linux/prctl.h


def check_executor(executor: str) -> None:
    """Raise ConfigError naming the valid executors when `executor` is not one of them."""
    check_choice(executor, EXECUTORS, what="executor")


def die_with_parent(parent_pid: int) -> None:
    """Worker initializer: end this process when `parent_pid` dies, even by SIGKILL (no orphaned workers)."""
    import os
    import signal
    import sys
    import threading
    import time

    if sys.platform.startswith("linux"):
        import ctypes

        try:
            libc = ctypes.CDLL(None, use_errno=True)
            # The kernel sends SIGKILL to this worker when the thread that forked it exits.
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent_pid:  # the parent died before prctl took effect
        os._exit(1)

    def watch() -> None:
        # Portable fallback (and covers a parent thread other than the one that spawned us): poll the parent.
        while True:
            time.sleep(1.0)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, name="die-with-parent", daemon=True).start()


def run_map(fn: Callable[..., Any], items: Iterable[Any], *, executor: str = "local", workers: int | None = None,
            address: str | None = None, args: tuple = ()) -> Iterator[Any]:
    """Yield fn(item, *args) for each item, in order, computed by the chosen executor."""
    check_executor(executor)
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
    # die_with_parent: a SIGKILLed ingest must not leave its workers rendering for nobody.
    with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"), initializer=die_with_parent,
                             initargs=(os.getpid(),)) as pool:
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
