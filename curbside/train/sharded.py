"""A vector env of N shards of envs: shard 0 stepped in this process, the others each in a worker process, all at
once; one hand-over per worker per step instead of one per env.

Gymnasium's AsyncVectorEnv runs one env per process and blocks on a pipe for every hand-over. On this 2-core VM a
PointNav step takes ~1 ms, and a vector env of two such workers reached only 0.7-1.1x one process although two
independent processes reach 2.1x (benchmarks/vector_envs.py): a worker that blocks gives up its core, and every
wake-up costs more than the pipe round trip itself. Here the parent steps shard 0 itself while the workers step
theirs (N processes for N shards, not N + 1), and both sides hand over through semaphores polled for `spin`
seconds before blocking, so a worker waiting for the next action keeps its core while the policy runs, and still
sleeps through a PPO update. Spinning is turned off when there are more processes than cores.

The hand-over stays in lock-step whatever fails: an exception in the local shard is raised once every worker has
replied, and a call interrupted while it waits (KeyboardInterrupt) has its replies read before the next; a worker
that fails or dies closes the vector env and raises RuntimeError; a worker whose parent is gone (killed, even by
SIGKILL) exits within a couple of seconds; replies larger than a socket's buffer pass (see INLINE_BYTES).

A step passes through shared memory only (`Shared`): actions, observations, rewards and flags in shared arrays, the
infos pickled into a per-worker buffer, the semaphores the only system calls; other commands, and infos too big for
the buffer, go through the worker's pipe. The local shard's infos are batched while the workers step.

Semantics are Gymnasium's with `autoreset_mode=SAME_STEP`: a finished env is reset in the same step, its last
observation and info under `final_obs` and `final_info` (a test checks the arrays and infos against
`SyncVectorEnv` on the same seeds).
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import pickle
import time
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np
from gymnasium.error import AlreadyPendingCallError, ClosedEnvironmentError, NoAsyncCallError
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import CloudpickleWrapper, batch_space

from curbside.train.handover import PIPE, SPIN_S, STEP, Shared, hand_over, run_command, serve, wait_for

if TYPE_CHECKING:
    from multiprocessing.context import ForkContext, ForkServerContext, SpawnContext


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS reports one)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


class ShardedVectorEnv(VectorEnv):
    """`len(env_fns)` envs in `workers` shards (env i in shard i * workers // n); Box observations only.

    `local`: shard 0 runs in this process (workers - 1 worker processes), else every shard has a process. `spin`:
    seconds each side polls before blocking (SPIN_S; 0 where processes outnumber cores). `step_async`/`step_wait`
    let the caller work while the workers step (SB3 does, through VectorEnvAdapter); the local shard steps in
    `step_wait`.
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gym.Env]],
        workers: int,
        context: str = "forkserver",
        local: bool = True,
        spin: float | None = None,
    ) -> None:
        n = len(env_fns)
        if not 1 <= workers <= n:
            raise ValueError(f"workers must be in [1, {n}] (the number of envs), got {workers}")
        probe = env_fns[0]()
        self.single_observation_space, self.single_action_space = probe.observation_space, probe.action_space
        self.render_mode = probe.render_mode
        probe.close()
        if not isinstance(self.single_observation_space, gym.spaces.Box):
            raise ValueError(
                f"ShardedVectorEnv shares Box observations only, got {self.single_observation_space}; "
                "use gymnasium's AsyncVectorEnv for other spaces"
            )
        self.num_envs = n
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        self.metadata = {**type(self).metadata, "render_modes": []}
        # typeshed types get_context of a str as BaseContext; each start method's context has Process.
        ctx = cast("ForkContext | ForkServerContext | SpawnContext", mp.get_context(context))
        self._shared = Shared(ctx, n, workers, self.single_observation_space, self.single_action_space)
        self._arrays = self._shared.views()
        self._obs = self._arrays["obs"]
        self._bounds = [(w * n // workers, (w + 1) * n // workers) for w in range(workers)]
        cores = usable_cores()
        processes = workers if local else workers + 1  # the parent waits (spins) too
        self._spin = (SPIN_S if processes <= cores else 0.0) if spin is None else float(spin)
        self._pending: list[Any] | None = None  # the shards' actions between step_async and step_wait
        self._local: list[gym.Env] = []
        self._local_bounds = self._bounds[0] if local else (0, 0)
        self._pipes: list[Connection] = []
        self._procs: list[Any] = []
        self._sems: list[tuple[Any, Any]] = []  # (go, done) per worker
        self._owed: list[bool] = []  # per worker: a reply not read yet (a call interrupted in _gather leaves some)
        self.closed = False
        for w, (lo, hi) in enumerate(self._bounds[1:] if local else self._bounds):
            parent, child = ctx.Pipe()
            go, done = ctx.Semaphore(0), ctx.Semaphore(0)
            fns = [CloudpickleWrapper(fn) for fn in env_fns[lo:hi]]  # closures travel to forkserver/spawn workers
            proc = ctx.Process(target=serve, args=(fns, child, go, done, self._spin, self._shared, w, lo), daemon=True)
            proc.start()
            child.close()
            self._pipes.append(parent)
            self._procs.append(proc)
            self._sems.append((go, done))
            self._owed.append(True)  # "ok" once its envs are built
        try:
            self._local = [fn() for fn in env_fns[slice(*self._local_bounds)]]  # built while the workers build theirs
        except Exception:
            self.close(terminate=True)
            raise
        self._gather()  # every worker built its envs (or the first failure is raised here)

    def _shards(self, per_shard: Sequence[Any] | None, data: Any) -> list[Any]:
        return list(per_shard) if per_shard is not None else [data] * len(self._bounds)

    def _run(self, command: str, per_shard: Sequence[Any] | None = None, data: Any = None) -> list[Any]:
        """Send `command` to every worker, carry it out on the local shard meanwhile, and gather the replies."""
        if self._pending is not None:
            raise AlreadyPendingCallError(f"{command} while a step is pending; call step_wait first", "step")
        self._send(command, per_shard, data)
        return self._finish(command, per_shard, data)

    def _send(self, command: str, per_shard: Sequence[Any] | None = None, data: Any = None) -> None:
        if self.closed:
            raise ClosedEnvironmentError(f"{command} on a closed ShardedVectorEnv")
        if any(self._owed):
            self._drain()  # replies a call interrupted in _gather (KeyboardInterrupt) left behind
            if self.closed:
                raise ClosedEnvironmentError(f"{command} on a ShardedVectorEnv whose worker died")
        first = 1 if self._local_bounds[1] else 0
        shared_step = command == "step" and "actions" in self._arrays
        for w, ((lo, hi), payload) in enumerate(zip(self._bounds[first:], self._shards(per_shard, data)[first:])):
            if shared_step:  # after the drain above: a step an interrupted call left running has read its own
                self._arrays["actions"][lo:hi] = payload
            try:
                self._post(w, (command, None if shared_step else payload))
            except OSError:  # BrokenPipeError: the worker is gone
                self._died(w)
            self._owed[w] = True

    def _post(self, w: int, message: tuple[str, Any]) -> None:
        """Hand worker `w` a command: a step on the shared actions by its command word alone, else by its pipe."""
        go = self._sems[w][0]
        if message[0] == "step" and message[1] is None:
            self._arrays["command"][w] = STEP
            go.release()
        else:
            self._arrays["command"][w] = PIPE
            hand_over(self._pipes[w], go, message)

    def _finish(self, command: str, per_shard: Sequence[Any] | None, data: Any) -> list[Any]:
        local = []
        if self._local_bounds[1]:
            try:
                payload = self._shards(per_shard, data)[0]
                local = [run_command(self._local, self._arrays, self._local_bounds[0], command, payload)]
            except BaseException:
                self._drain()  # the workers' replies to this command, or the next command would read them
                raise
        return local + self._gather()

    def _drain(self) -> None:
        """Take the workers' replies still owed and drop them (a failure among them closes the env)."""
        with contextlib.suppress(RuntimeError):  # _gather closed the env; the caller raises its own error
            self._gather()

    def _died(self, w: int) -> None:
        """Close the vector env and raise RuntimeError: worker `w` is gone."""
        proc = self._procs[w]
        proc.join(timeout=1.0)
        self.close(terminate=True)
        raise RuntimeError(
            f"ShardedVectorEnv worker {w} (pid {proc.pid}) died (exit code {proc.exitcode}); the vector env is closed"
        )

    def _gather(self) -> list[Any]:
        """The replies owed, worker by worker; RuntimeError (the env closed) when a worker failed or died."""
        out: list[Any] = []
        errors: list[Any] = []
        for w, ((_, done), pipe, proc) in enumerate(zip(self._sems, self._pipes, self._procs)):
            if not self._owed[w]:
                continue
            try:
                wait_for(done, self._spin, proc.is_alive)
                size = int(self._arrays["reply"][w])
                status, data = ("ok", pickle.loads(self._arrays["infos"][w, :size].data)) if size >= 0 else pipe.recv()
            except (EOFError, OSError):
                status = "died"
            if status == "died":
                self._died(w)
            self._owed[w] = False
            (errors if status == "error" else out).append(data)
        if errors:
            self.close(terminate=True)
            raise RuntimeError(f"a ShardedVectorEnv worker failed:\n{errors[0]}")
        return out

    def _batched(self, infos: list[dict[str, Any]]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for i, info in enumerate(infos):
            out = self._add_info(out, info, i)
        return out

    def _add_info(self, vector_infos: dict[str, Any], env_info: dict[str, Any], env_num: int) -> dict[str, Any]:
        """Gymnasium's VectorEnv._add_info, the same arrays (a test compares them), at a third of its cost: a key
        an earlier env already gave (every key but the first env's, as envs give the same keys step after step)
        only sets its value and mask; Gymnasium's allocated a mask and retested the value's type every time."""
        n = self.num_envs
        for key, value in env_info.items():
            array = vector_infos.get(key)
            mask_key = "_" + key
            if array.__class__ is np.ndarray and value.__class__ is not dict and key != "final_obs":
                mask = vector_infos.get(mask_key)
                if mask is not None:  # None: `key` is itself an earlier key's mask ("_x" after "x")
                    array[env_num] = value
                    mask[env_num] = True
                    continue
            if key == "final_obs":  # unbatched: an object array of the envs' own observations
                if array is None:
                    array = np.empty(n, dtype=object)  # None everywhere
                array[env_num] = value
            elif isinstance(value, dict):
                array = self._add_info({} if array is None else array, value, env_num)
            else:
                if array is None:  # else an earlier env's (a dict, when envs disagree: Gymnasium keeps it too)
                    kind = type(value)
                    if kind in (int, float, bool) or issubclass(kind, np.number):
                        array = np.zeros(n, dtype=kind)
                    elif isinstance(value, np.ndarray):
                        array = np.zeros((n, *value.shape), dtype=value.dtype)
                    else:
                        array = np.empty(n, dtype=object)  # None everywhere
                array[env_num] = value
            mask = vector_infos.get(mask_key)
            if mask is None:
                mask = np.zeros(n, dtype=np.bool_)
            mask[env_num] = True
            vector_infos[key], vector_infos[mask_key] = array, mask
        return vector_infos

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every env (`seed` an int gives env i seed + i, as Gymnasium's vector envs do)."""
        seeds = (
            [seed + i for i in range(self.num_envs)]
            if isinstance(seed, int)
            else (list(seed) if seed is not None else [None] * self.num_envs)
        )
        if len(seeds) != self.num_envs:
            raise ValueError(f"reset got {len(seeds)} seeds for {self.num_envs} envs")
        infos = [i for part in self._run("reset", [(seeds[lo:hi], options) for lo, hi in self._bounds]) for i in part]
        return self._obs.copy(), self._batched(infos)

    def step_async(self, actions: np.ndarray) -> None:
        """Send every worker its shard's actions (the local shard's wait for step_wait)."""
        if self._pending is not None:
            raise AlreadyPendingCallError("step_async while a step is pending; call step_wait first", "step")
        actions = np.asarray(actions)
        if "actions" in self._arrays and actions.shape != self._arrays["actions"].shape:
            raise ValueError(
                f"step got actions of shape {actions.shape}; this vector env of {self.num_envs} envs "
                f"takes {self._arrays['actions'].shape}"
            )
        pending = [actions[lo:hi] for lo, hi in self._bounds]
        self._send("step", pending)
        self._pending = pending

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step the local shard, wait for every worker: observations, rewards, terminations, truncations, infos."""
        if self._pending is None:
            raise NoAsyncCallError("step_wait without a pending step; call step_async first", "step")
        pending, self._pending = self._pending, None
        infos: dict[str, Any] = {}
        lo, hi = self._local_bounds
        if hi:
            try:
                local = run_command(self._local, self._arrays, lo, "step", pending[0])
            except BaseException:
                self._drain()  # the workers' replies to this step, or the next command would read them
                raise
            for i, info in enumerate(local, lo):  # batched while the workers step
                infos = self._add_info(infos, info, i)
        bounds = self._bounds[1:] if hi else self._bounds
        for (lo, _), part in zip(bounds, self._gather()):
            for i, info in enumerate(part, lo):
                infos = self._add_info(infos, info, i)
        a = self._arrays
        return self._obs.copy(), a["rewards"].copy(), a["terms"].copy(), a["truncs"].copy(), infos

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env once (finished ones are reset in the same step)."""
        self.step_async(actions)
        return self.step_wait()

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """An attribute of every (wrapped) env."""
        return tuple(v for part in self._run("get_attr", data=name) for v in part)

    def set_attr(self, name: str, values: Any) -> None:
        """Set an attribute of every env (one value, or one per env)."""
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        self._run("set_attr", [(name, values[lo:hi]) for lo, hi in self._bounds])

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call a method of every env (or read an attribute that is not callable)."""
        return tuple(v for part in self._run("call", data=(name, args, kwargs)) for v in part)

    def close(self, terminate: bool = False, **kwargs: Any) -> None:
        """Stop the workers (politely unless `terminate`; one that does not stop within 10 s is terminated)."""
        if getattr(self, "closed", True):
            return
        self.closed = True
        self._pending = None
        try:
            for w, proc in enumerate(self._procs):
                if not terminate and proc.is_alive():
                    if self._owed[w]:
                        self._discard(w, 10.0)  # a worker blocked sending a pending step's reply never reads "close"
                    try:
                        self._post(w, ("close", None))
                    except OSError:
                        pass
            for pipe, proc in zip(self._pipes, self._procs):
                proc.join(timeout=10)
                if proc.is_alive():
                    proc.terminate()
                    proc.join()
                pipe.close()
        finally:
            for env in self._local:
                env.close()

    def _discard(self, w: int, timeout: float) -> None:
        """Read and drop worker `w`'s owed reply if it comes within `timeout` seconds."""
        (_, done), pipe, proc = self._sems[w], self._pipes[w], self._procs[w]
        deadline = time.monotonic() + timeout
        while proc.is_alive() and time.monotonic() < deadline:
            if done.acquire(timeout=0.05):
                # A step's infos in the shared buffer leave nothing in the pipe.
                if self._arrays["reply"][w] < 0 and pipe.poll(max(deadline - time.monotonic(), 0.0)):
                    try:
                        pipe.recv()
                    except (EOFError, OSError):
                        pass
                self._owed[w] = False
                return
