"""Import pybullet without its `pybullet build time: ...` banner.

pybullet's C module init prints that line on every import (to stderr in the wheels we install, to stdout in some
builds), so every `curbside sim` command began with it: noise above results and before the one error line, and
a risk to JSON on stdout (the catalog validator and the retrieval renderer use it too). Sim modules import it as
`from kernel.quiet import pybullet as p` (this module's `__getattr__`), so the one real import is the quiet one;
later imports find it in sys.modules.
"""

from __future__ import annotations

import os
import sys
from types import ModuleType


def _flush_c_stdout() -> None:
    """Flush C stdio's buffers (printf output to a pipe waits there), so the banner goes where fds 1/2 point now."""
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # no libc handle on this platform: nothing buffered that we can reach
        pass


def import_pybullet() -> ModuleType:
    """`import pybullet` with file descriptors 1 and 2 pointed at /dev/null while its C init prints the banner."""
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, ValueError, OSError):
            pass
    saved: list[tuple[int, int]] = []
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            for fd in (1, 2):
                try:
                    saved.append((fd, os.dup(fd)))
                except OSError:  # this fd is closed: nothing to silence there
                    continue
                os.dup2(devnull, fd)
        finally:
            os.close(devnull)
        import pybullet

        _flush_c_stdout()
    finally:
        for fd, copy in saved:
            os.dup2(copy, fd)
            os.close(copy)
    return pybullet


def __getattr__(name: str) -> ModuleType:
    """`from kernel.quiet import pybullet as p`: pybullet imported through `import_pybullet` (no banner)."""
    if name == "pybullet":
        return import_pybullet()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
