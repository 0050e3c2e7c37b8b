"""The executor options every sharded command takes (`--executor local|process|ray`, `--workers`, `--address`)."""

from __future__ import annotations

from enum import Enum
from typing import Any

import typer

from curbside.cli.errors import UsageError

# kernel.executors.EXECUTORS, as an Enum so `--help` lists them without importing the kernel's executors.
Executor = Enum("Executor", {"local": "local", "process": "process", "ray": "ray"}, type=str)
EXECUTOR_HELP = (
    "Where the work runs: local (this process), process (a pool of --workers processes) or ray (a Ray "
    "cluster: --address, or one started here with --workers CPUs). Every executor writes the same bytes."
)
ADDRESS_HELP = (
    "Ray cluster address with --executor ray: the HEAD:6379 that `ray start --head` prints, or auto "
    "for the cluster this node joined (default: a local cluster for this run)."
)


def executor_option(default: str = "local") -> Any:
    """The --executor option."""
    return typer.Option(default, help=EXECUTOR_HELP)


def address_option() -> Any:
    """The --address option."""
    return typer.Option(None, help=ADDRESS_HELP)


def workers_option(
    default: int | None = None,
    help: str = "Worker processes (process), or items at once on the cluster (ray); default: every core / cluster CPU.",
) -> Any:
    """The --workers option."""
    return typer.Option(default, min=1, max=1024, help=help)


def check_executor_args(executor: Any, address: str | None) -> str:
    """The executor's name; UsageError when --address is given without --executor ray."""
    name = executor.value if isinstance(executor, Enum) else str(executor)
    if address is not None and name != "ray":
        raise UsageError(f"--address {address} names a Ray cluster; add --executor ray (or leave out --address)")
    return name
