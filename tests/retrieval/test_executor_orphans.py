"""Process-executor workers die with their parent: a SIGKILLed ingest leaves no worker rendering for nobody."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

SCRIPT = """
import os, sys, time
from kernel.executors import run_map


def slow(i, folder):
    open(os.path.join(folder, str(os.getpid())), "w").close()  # tell the test which pid works
    time.sleep(120)
    return i


if __name__ == "__main__":
    for _ in run_map(slow, range(4), executor="process", workers=2, args=(sys.argv[1],)):
        pass
"""


def _alive(pid: int) -> bool:
    """Whether `pid` runs (a zombie waiting for init to reap it counts as dead)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False
    return state != "Z"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_workers_die_when_the_parent_is_killed(tmp_path: Path) -> None:
    script = tmp_path / "parent.py"
    script.write_text(SCRIPT)
    pids_dir = tmp_path / "pids"
    pids_dir.mkdir()
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    parent = subprocess.Popen([sys.executable, str(script), str(pids_dir)], cwd=REPO, env=env)
    workers: list[int] = []
    try:
        deadline = time.monotonic() + 90
        while len(workers) < 2 and time.monotonic() < deadline:
            time.sleep(0.2)
            workers = [int(p.name) for p in pids_dir.iterdir()]
        assert len(workers) == 2, "the two workers never started"
        assert all(_alive(p) for p in workers)
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 15
        while any(_alive(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not [p for p in workers if _alive(p)], "workers outlived their SIGKILLed parent"
    finally:
        parent.kill()
        for p in workers:  # only the workers this test started, should the assertion have failed
            if _alive(p):
                os.kill(p, signal.SIGKILL)
