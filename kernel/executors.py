"""Executors that map a per-item function over items: `local` (in-process), `process` (a local pool) and `ray`
(a Ray cluster: this machine, or every node of one started with `ray start`).

Every executor yields results in input order, so a caller that writes or aggregates what it is given produces the
same bytes whichever executor, worker count or cluster ran the work. Callers make each item's result depend on the
item alone (a scene's or episode's seed is its index), which is what lets a retried item give the same answer.

Fault handling: on `ray`, a worker process that dies mid-item (killed, out of memory, a lost node) fails only its
task, and Ray runs the task again (`max_retries`); the result holds every item exactly once because results are
collected per item index, never appended by workers. A `process` pool cannot recover a dead worker: it raises.

This module is part of the kernel (docs/architecture.md): it imports no room, so `sim`, `retrieval` and the CLI all
share it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any

from kernel.config import ConfigError, check_choice

EXECUTORS = ("local", "process", "ray")
MAX_RETRIES = 3  # Ray's own default for tasks; kept explicit because the fault tests rely on it
PR_SET_PDEATHSIG = 1  # linux/prctl.h
Progress = Callable[[int], None]  # called with the number of items just finished (in any order)

_STATE: dict[str, tuple[str, Any]] = {}  # per worker process: slot -> (key, object), see worker_state


def check_executor(executor: str) -> None:
    """Raise ConfigError naming the valid executors when `executor` is not one of them."""
    check_choice(executor, EXECUTORS, what="executor")


def check_workers(workers: int | None) -> None:
    """Raise ConfigError unless `workers` is None (every core or cluster CPU) or an integer in [1, 1024]."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= 1024):
        raise ConfigError(f"workers must be an integer in [1, 1024], got {workers!r}")


def worker_state(slot: str, key: str, factory: Callable[[], Any]) -> Any:
    """The object in `slot` of this process, built by `factory` when the slot is empty or holds another `key`.

    Worker processes run many items; an env or a catalog reader built once per process (not once per item) is
    what makes sharding pay. An object replaced in its slot is closed.
    """
    held = _STATE.get(slot)
    if held is not None and held[0] == key:
        return held[1]
    if held is not None:
        _close(held[1])
    obj = factory()
    _STATE[slot] = (key, obj)
    return obj


def release_worker_state() -> None:
    """Close and forget every object `worker_state` holds in this process (the local executor's end of a run)."""
    while _STATE:
        _close(_STATE.popitem()[1][1])


def _close(obj: Any) -> None:
    close = getattr(obj, "close", None)
    if callable(close):
        close()


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


def run_map(
    fn: Callable[..., Any],
    items: Iterable[Any],
    *,
    executor: str = "local",
    workers: int | None = None,
    address: str | None = None,
    args: tuple = (),
    progress: Progress | None = None,
    max_retries: int = MAX_RETRIES,
    nodes: dict[str, int] | None = None,
) -> Iterator[Any]:
    """Yield fn(item, *args) for each item, in order, computed by the chosen executor.

    `workers`: processes (`process`), or at most this many items at once on the cluster (`ray`; a local cluster is
    started with this many CPUs). `address`: a running Ray cluster (`ray start --head` prints it; "auto" finds the
    one on this node). `progress(n)` is called as items finish, in whatever order the workers finish them.
    `items` may be endless: work is submitted a window at a time, and closing the generator cancels what is left.
    `nodes`, when given, is filled with the number of items each node finished (Ray node ids; "local" otherwise).
    """
    check_executor(executor)
    check_workers(workers)
    if address is not None and executor != "ray":
        raise ConfigError(f"an address ({address}) is a Ray cluster's: use it with executor 'ray', not {executor!r}")
    if executor == "local":
        try:
            for item in items:
                result = fn(item, *args)
                if progress:
                    progress(1)
                if nodes is not None:
                    nodes["local"] = nodes.get("local", 0) + 1
                yield result
        finally:
            release_worker_state()
    elif executor == "process":
        for result in _process_map(fn, items, workers, args, progress):
            if nodes is not None:
                nodes["local"] = nodes.get("local", 0) + 1
            yield result
    else:
        yield from _ray_map(fn, items, workers, address, args, progress, max_retries, nodes)


def _process_map(
    fn: Callable[..., Any], items: Iterable[Any], workers: int | None, args: tuple, progress: Progress | None
) -> Iterator[Any]:
    import multiprocessing as mp
    import os
    from collections import deque
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    workers = workers or os.cpu_count() or 1
    # spawn: torch and pybullet state must not be forked from a parent that already loaded them.
    # die_with_parent: a SIGKILLed run must not leave its workers working for nobody.
    pool = ProcessPoolExecutor(
        max_workers=workers, mp_context=mp.get_context("spawn"), initializer=die_with_parent, initargs=(os.getpid(),)
    )
    try:
        window: deque = deque()
        counted: set = set()
        it = iter(items)
        exhausted = False
        while True:
            while not exhausted and len(window) < 2 * workers:
                try:
                    window.append(pool.submit(fn, next(it), *args))
                except StopIteration:
                    exhausted = True
            if not window:
                return
            if not window[0].done():
                wait(list(window), return_when=FIRST_COMPLETED)
            for f in window:
                if f.done() and f not in counted:
                    counted.add(f)
                    if progress:
                        progress(1)
            while window and window[0].done():
                f = window.popleft()
                # A future may finish between the count above and this check: count it here, once.
                if f not in counted and progress:
                    progress(1)
                counted.discard(f)
                yield f.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def connect_ray(workers: int | None = None, address: str | None = None) -> bool:
    """Connect to the Ray cluster at `address` (default: $RAY_ADDRESS), or start one on this machine with `workers`
    CPUs (every core when None); True when this call started or joined it (the caller then shuts it down), False
    if already connected."""
    import logging
    import os

    try:
        import ray
    except ImportError as exc:
        raise ConfigError("the ray executor needs Ray: pip install 'curbside[cluster]' (or ray[default])") from exc
    if ray.is_initialized():
        return False
    address = address or os.environ.get("RAY_ADDRESS") or None  # Ray's own convention for "the cluster to use"
    os.environ.setdefault("RAY_AUTH_MODE", "disabled")  # a local cluster for one run: no token to hand out
    quiet: dict[str, Any] = {
        "include_dashboard": False,
        "log_to_driver": False,
        "logging_level": logging.WARNING,
        "configure_logging": True,
    }
    if address:
        _check_reachable(address)
        try:
            ray.init(address=address, **quiet)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise ConfigError(
                f"cannot reach a Ray cluster at {address!r} ({exc}); start one with "
                "`ray start --head` and pass the address it prints, or leave out --address"
            ) from exc
    else:
        # Ray lowers its workers' priority by 15 by default (to keep its raylet responsive); here the workers are
        # the work, and at nice +15 they lose every core to any other job (measured: 2 workers no faster than 1
        # beside one busy process). They run at this process's priority, as `process` workers do.
        os.environ.setdefault("RAY_worker_niceness", "0")
        # address='local': a new cluster for this run, never one found in /tmp/ray or among this machine's processes
        ray.init(address="local", num_cpus=workers or os.cpu_count() or 1, **quiet)
    return True


def _check_reachable(address: str, timeout: float = 5.0) -> None:
    """ConfigError when a HOST:PORT address does not answer a TCP connect (Ray itself would retry for minutes)."""
    import socket

    host, sep, port = address.rpartition(":")
    if not sep or "/" in address or not port.isdigit():
        return  # "auto", ray://..., or a form Ray explains itself
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as exc:
        raise ConfigError(
            f"cannot reach a Ray cluster at {address!r} ({exc.strerror or exc}); start one with "
            "`ray start --head` and pass the address it prints, or leave out --address"
        ) from None


def in_flight(workers: int | None, cpus: int) -> int:
    """How many tasks the ray executor keeps submitted at once on a cluster of `cpus` CPUs."""
    # When the cluster has no more CPUs than `workers` (the local cluster this executor starts has exactly that
    # many), Ray itself runs at most `cpus` tasks at once, and two a CPU keep every worker busy while the driver
    # collects a result and submits the next: one in flight left a lone worker idle for each round trip (2 workers
    # went from 1.6-1.76x to 1.86-2.12x of one). On a larger cluster `workers` is the limit on tasks in flight.
    cpus = max(cpus, 1)  # a cluster reporting less than one CPU: with none in flight the map would return nothing
    return 2 * cpus if workers is None or cpus <= workers else workers


def on_node(fn: Callable[..., Any], item: Any, *args: Any) -> tuple[str, Any]:
    """(id of the Ray node this runs on, fn(item, *args)): the task the ray executor submits."""
    import ray

    return ray.get_runtime_context().get_node_id(), fn(item, *args)


def _ray_map(
    fn: Callable[..., Any],
    items: Iterable[Any],
    workers: int | None,
    address: str | None,
    args: tuple,
    progress: Progress | None,
    max_retries: int,
    nodes: dict[str, int] | None,
) -> Iterator[Any]:
    started = connect_ray(workers, address)
    import ray

    pending: dict[Any, int] = {}  # object ref -> item index
    try:
        # max_retries: Ray reruns a task whose worker process died (not one whose code raised: that is a bug or
        # bad input, and would fail again).
        # The task is `on_node` named after fn (workers are titled ray::<name> while they run it). SPREAD: with two
        # tasks a CPU in flight (`in_flight`), Ray's default policy may queue them all on the driver's node while the
        # other nodes start their workers (seen on a loaded 3-node test cluster: 8 of 8 on the head).
        remote = ray.remote(num_cpus=1, max_retries=max_retries, scheduling_strategy="SPREAD")(on_node).options(
            name=getattr(fn, "__name__", "item")
        )
        shared = [ray.put(fn)] + [ray.put(a) for a in args]
        capacity = in_flight(workers, int(ray.cluster_resources().get("CPU", 1)))
        done: dict[int, Any] = {}
        it = enumerate(items)
        exhausted, next_out = False, 0
        while True:
            while not exhausted and len(pending) < capacity:
                try:
                    i, item = next(it)
                except StopIteration:
                    exhausted = True
                    break
                pending[remote.remote(shared[0], item, *shared[1:])] = i
            if not pending and not done:
                return
            if next_out not in done:
                ready, _ = ray.wait(list(pending), num_returns=1)
                for ref in ready:
                    i = pending.pop(ref)
                    try:
                        node, done[i] = ray.get(ref)
                    except ray.exceptions.RayTaskError as exc:  # the item's own exception, as `local` raises it
                        raise exc.as_instanceof_cause() from None
                    if nodes is not None:
                        nodes[node] = nodes.get(node, 0) + 1
                    if progress:
                        progress(1)
            while next_out in done:
                yield done.pop(next_out)
                next_out += 1
    finally:
        for ref in pending:
            ray.cancel(ref)
        if started:
            ray.shutdown()
