"""ShardedVectorEnv's hand-over stays in lock-step, or closes and says why, whatever goes wrong: an exception in the
local shard, a call interrupted while it waits, replies larger than a socket's buffer, a worker that dies, close()
with a step pending, a parent killed by SIGKILL (tests/train/toy_envs.py: a cheap env that fails on request)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from gymnasium.error import AlreadyPendingCallError, ClosedEnvironmentError, NoAsyncCallError

from curbside.train.sharded import ShardedVectorEnv
from tests.train.toy_envs import BIG, EXIT, RAISE, SLOW, counters

ROOT = Path(__file__).resolve().parents[2]


class Interrupted(Exception):
    """What the test's SIGALRM raises in the parent."""


@contextmanager
def alarm(seconds: float) -> Iterator[None]:
    """Raise Interrupted in this process after `seconds` (a hang fails the test instead of stalling the suite)."""

    def ring(signum: int, frame: object) -> None:
        raise Interrupted

    old = signal.signal(signal.SIGALRM, ring)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _in_step(venv: ShardedVectorEnv, info: dict) -> None:
    """Every env's reply belongs to the step whose observations are in the shared array."""
    obs = venv._obs
    np.testing.assert_array_equal(np.asarray(info["n"], dtype=np.float64), obs[:, 1])


def _actions(n: int, **special: float) -> np.ndarray:
    a = np.zeros((n, 1))
    for k, v in special.items():
        a[int(k[1:])] = v
    return a


def test_an_exception_in_the_local_shard_leaves_the_workers_in_step() -> None:
    venv = ShardedVectorEnv(counters(4), workers=2)
    try:
        with alarm(30):
            venv.reset(seed=0)
            with pytest.raises(ValueError, match="env 0 was asked to fail"):
                venv.step(_actions(4, e0=RAISE))
            for _ in range(2):  # without draining, the workers' replies to the failed step came one step late
                obs, *_, info = venv.step(_actions(4))
                _in_step(venv, info)
            assert obs[2:, 1].tolist() == [3.0, 3.0]  # the workers' envs stepped in the failed call too
    finally:
        venv.close()


def test_a_call_interrupted_while_it_waits_leaves_no_stale_reply() -> None:
    venv = ShardedVectorEnv(counters(2), workers=2, local=False)
    try:
        venv.reset(seed=0)
        with pytest.raises(Interrupted), alarm(0.3):
            venv.step(_actions(2, e1=SLOW))  # worker 1 sleeps 1 s; the parent is interrupted waiting for it
        with alarm(30):
            obs, *_, info = venv.step(_actions(2))
        _in_step(venv, info)
        assert obs[:, 1].tolist() == [2.0, 2.0]
    finally:
        venv.close()


def test_a_step_an_interrupt_left_running_keeps_its_own_actions() -> None:
    venv = ShardedVectorEnv(counters(2), workers=2, local=False)
    pid = venv._procs[1].pid
    try:
        venv.reset(seed=0)
        os.kill(pid, signal.SIGSTOP)  # worker 1 cannot read its step's actions before the parent gives up
        try:
            with pytest.raises(Interrupted), alarm(0.3):
                venv.step(_actions(2))
            threading.Timer(0.5, os.kill, (pid, signal.SIGCONT)).start()
            with alarm(30):
                # The next step's actions must not reach the interrupted step (it ran on them, raised, and the
                # drain closed the env): the next step is the one that fails.
                venv.step_async(_actions(2, e1=RAISE))
                with pytest.raises(RuntimeError, match="env 1 was asked to fail"):
                    venv.step_wait()
        finally:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGCONT)
    finally:
        venv.close()


def test_replies_and_commands_larger_than_a_socket_buffer_do_not_deadlock() -> None:
    venv = ShardedVectorEnv(counters(4), workers=2)
    try:
        with alarm(30):
            venv.reset(seed=0)
            *_, info = venv.step(_actions(4, e0=BIG, e1=BIG, e2=BIG, e3=BIG))  # 800 KB from the worker
            assert [float(b[0]) for b in info["big"]] == [0.0, 1.0, 2.0, 3.0]
            frames = venv.call("frame")
            assert [float(f[-1]) for f in frames] == [0.0, 1.0, 2.0, 3.0]
            venv.set_attr("payload", [np.full(100_000, k) for k in range(4)])  # 1.6 MB to the worker
            assert [int(v[-1]) for v in venv.get_attr("payload")[2:]] == [2, 3]
    finally:
        venv.close()


def test_a_worker_that_dies_closes_the_env_and_says_so() -> None:
    venv = ShardedVectorEnv(counters(4), workers=2)
    procs = list(venv._procs)
    with alarm(30):
        venv.reset(seed=0)
        with pytest.raises(RuntimeError, match=r"worker 0 \(pid \d+\) died \(exit code 3\)"):
            venv.step(_actions(4, e3=EXIT))
    assert venv.closed and not any(p.is_alive() for p in procs)
    with pytest.raises(ClosedEnvironmentError):
        venv.step(_actions(4))


def test_close_with_a_step_pending_is_prompt_and_calls_out_of_turn_are_refused() -> None:
    venv = ShardedVectorEnv(counters(4), workers=2)
    procs = list(venv._procs)
    venv.reset(seed=0)
    venv.step_async(_actions(4))
    with pytest.raises(AlreadyPendingCallError):
        venv.step_async(_actions(4))
    with pytest.raises(AlreadyPendingCallError):
        venv.reset(seed=0)
    venv.step_wait()
    with pytest.raises(NoAsyncCallError):
        venv.step_wait()
    venv.step_async(_actions(4, e2=BIG, e3=BIG))  # the worker blocks sending this reply until it is read
    t0 = time.perf_counter()
    venv.close()
    assert time.perf_counter() - t0 < 5.0  # it was 10 s: close() waited for the blocked worker, then killed it
    assert not any(p.is_alive() for p in procs)


def _gone(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0] in "ZX"
    except (FileNotFoundError, IndexError):
        return True


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads process states from /proc")
def test_workers_exit_when_their_parent_is_killed(tmp_path: Path) -> None:
    script = tmp_path / "parent.py"
    script.write_text(
        textwrap.dedent("""
        import time
        from curbside.train.sharded import ShardedVectorEnv
        from tests.train.toy_envs import counters

        if __name__ == "__main__":
            venv = ShardedVectorEnv(counters(3), workers=3)
            venv.reset(seed=0)
            print(" ".join(str(p.pid) for p in venv._procs), flush=True)
            time.sleep(120)
    """)
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    parent = subprocess.Popen([sys.executable, str(script)], cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    try:
        pids = [int(p) for p in parent.stdout.readline().split()]  # type: ignore[union-attr]
        assert len(pids) == 2
        parent.kill()  # SIGKILL: no atexit, no finalizers
        parent.wait()
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and not all(_gone(p) for p in pids):
            time.sleep(0.1)
        left = [p for p in pids if not _gone(p)]
        for p in left:
            os.kill(p, signal.SIGKILL)
        assert not left, f"workers {left} outlived their parent by 10 s"
    finally:
        if parent.poll() is None:
            parent.kill()


def test_discrete_actions_travel_by_pipe_and_bad_action_shapes_are_refused() -> None:
    from tests.train.toy_envs import Chooser

    venv = ShardedVectorEnv([lambda i=i: Chooser(i) for i in range(4)], workers=2)
    try:
        venv.reset(seed=0)
        _, rewards, terms, _, info = venv.step(np.array([0, 1, 2, 1]))
        np.testing.assert_array_equal(rewards, [0.0, 1.0, 2.0, 1.0])
        np.testing.assert_array_equal(terms, [False, False, True, False])
        # Env 2 ended and was reset in the same step: its step's info is under final_info.
        assert info["_a"].tolist() == [True, True, False, True] and info["a"][[0, 1, 3]].tolist() == [0, 1, 1]
        assert info["_final_obs"].tolist() == [False, False, True, False] and info["final_info"]["a"][2] == 2
    finally:
        venv.close()
    venv = ShardedVectorEnv(counters(4), workers=2)
    try:
        venv.reset(seed=0)
        with pytest.raises(ValueError, match=r"actions of shape \(4,\).*takes \(4, 1\)"):
            venv.step(np.zeros(4))
        _, _, _, _, info = venv.step(_actions(4))  # still in lock-step after the refusal
        _in_step(venv, info)
    finally:
        venv.close()
