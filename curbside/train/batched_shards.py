"""An SB3 VecEnv over a batched env cut into shards: shard 0 stepped in this process, each other shard in a worker
process, all at once.

A batched env (sim.batched) steps all its envs in one Python thread. SocialNav's crowds (an ORCA simulator an env) and
its LiDAR keep that thread busy for ~75 % of a PPO iteration under the `paper_realistic` protocol, and the training
process uses ~1.1 of two cores while it rolls out; only the PPO update uses both. Here the envs are split into one
batched env per core, env i in shard i * shards // n, and the shards step side by side: the parent sends the workers
their actions, steps its own shard, then reads theirs.

Env i keeps its seed (the outer VecEnv's seed + i, so the same draws as env i of one batched env) and its episodes;
what a shard shares among its own envs, the scenes it has built and each scene's route pool, it does not share with
the others, so a sharded run is reproducible for a given shard count, not equal to the unsharded one. A worker's
failure is raised in the parent as RuntimeError with the worker's traceback; a worker whose parent is gone exits.
"""

from __future__ import annotations

import multiprocessing as mp
import traceback
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvStepReturn

if TYPE_CHECKING:
    from multiprocessing.context import ForkContext, ForkServerContext, SpawnContext

MakeShard = Callable[[int], VecEnv]  # envs -> an SB3 VecEnv of them; picklable (a worker gets it)


def _serve(make: MakeShard, n: int, pipe: Connection) -> None:
    """A worker: build the shard, then answer the parent's commands until "close" or the parent is gone."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)  # one core a shard: BLAS and numba must not spread threads over the other shards' cores
    import numba

    numba.set_num_threads(1)
    try:
        shard = make(n)
    except Exception:
        pipe.send(("error", traceback.format_exc()))
        return
    pipe.send(("ok", None))
    while True:
        try:
            command, data = pipe.recv()
        except (EOFError, OSError):  # the parent is gone
            shard.close()
            return
        if command == "close":
            shard.close()
            return
        try:
            pipe.send(("ok", _run(shard, command, data)))
        except Exception:
            pipe.send(("error", traceback.format_exc()))


def _run(shard: VecEnv, command: str, data: Any) -> Any:
    """One command on a shard (in a worker, or the parent's own shard)."""
    if command == "step":
        shard.step_async(data)
        return shard.step_wait()
    if command == "reset":
        seeds, options = data
        shard._seeds = list(seeds)  # SB3's VecEnv.seed sets consecutive seeds; a shard's are the outer env's slice
        shard.set_options(options)
        return shard.reset(), shard.reset_infos
    if command == "get_attr":
        return shard.get_attr(data)
    if command == "set_attr":
        name, value, indices = data
        if indices:
            shard.set_attr(name, value, indices=indices)
        return None
    if command == "env_method":
        name, args, kwargs = data
        return shard.env_method(name, *args, **kwargs)
    if command == "env_is_wrapped":
        return shard.env_is_wrapped(data)
    raise ValueError(f"unknown shard command {command!r}")


class BatchedShards(VecEnv):
    """`n_envs` envs as `shards` batched envs built by `make_shard(count)`, shard 0 in this process."""

    def __init__(self, make_shard: MakeShard, n_envs: int, shards: int, context: str = "forkserver") -> None:
        if not 1 <= shards <= n_envs:
            raise ValueError(f"shards must be in [1, {n_envs}] (the number of envs), got {shards}")
        self.bounds = [(k * n_envs // shards, (k + 1) * n_envs // shards) for k in range(shards)]
        # typeshed types get_context of a str as BaseContext; each start method's context has Process.
        ctx = cast("ForkContext | ForkServerContext | SpawnContext", mp.get_context(context))
        self.pipes: list[Connection] = []
        self.procs: list[Any] = []
        self.closed = False
        for lo, hi in self.bounds[1:]:
            parent, child = ctx.Pipe()
            proc = ctx.Process(target=_serve, args=(make_shard, hi - lo, child), daemon=True)
            proc.start()
            child.close()
            self.pipes.append(parent)
            self.procs.append(proc)
        try:
            lo, hi = self.bounds[0]
            self.local = make_shard(hi - lo)  # built while the workers build theirs
            self._gather()
        except BaseException:
            self.close()
            raise
        super().__init__(n_envs, self.local.observation_space, self.local.action_space)

    # ------------------------------------------------------------------ commands to every shard
    def _died(self, w: int) -> str:
        self.procs[w].join(1.0)
        return (
            f"shard {w + 1}'s worker process died (exit code {self.procs[w].exitcode}; its traceback is above). A "
            'script that builds training envs at import time needs an `if __name__ == "__main__":` guard: the '
            "worker process imports it again"
        )

    def _gather(self) -> list[Any]:
        out = []
        for w, pipe in enumerate(self.pipes):
            try:
                status, value = pipe.recv()
            except (EOFError, OSError) as err:
                self.close()
                raise RuntimeError(self._died(w)) from err
            if status != "ok":
                self.close()
                raise RuntimeError(f"shard {w + 1} failed in its worker process:\n{value}")
            out.append(value)
        return out

    def _all(self, command: str, per_shard: Sequence[Any]) -> list[Any]:
        """Run `command` on every shard at once (per_shard[k] is shard k's data); the answers in shard order."""
        for w, (pipe, data) in enumerate(zip(self.pipes, per_shard[1:])):
            try:
                pipe.send((command, data))
            except OSError as err:  # BrokenPipeError: the worker is gone
                self.close()
                raise RuntimeError(self._died(w)) from err
        try:
            mine = _run(self.local, command, per_shard[0])
        except BaseException:
            self._gather()  # keep the workers in step before raising the local shard's error
            raise
        return [mine, *self._gather()]

    def _slices(self, values: Any) -> list[Any]:
        return [values[lo:hi] for lo, hi in self.bounds]

    # ------------------------------------------------------------------ SB3's VecEnv
    def reset(self) -> np.ndarray:
        """Reset every env with its seed (`seed`) and the options (`set_options`), used once."""
        seeds, options = list(self._seeds), self._options[0] or None
        if any(o != self._options[0] for o in self._options):
            raise ValueError("the sub-envs were given different reset options; pass one dict to set_options")
        parts = self._all("reset", [(s, options) for s in self._slices(seeds)])
        self.reset_infos = [info for _, infos in parts for info in infos]
        self._reset_seeds()
        self._reset_options()
        return np.concatenate([obs for obs, _ in parts])

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        """Every shard steps its envs at once; their observations, rewards, dones and infos in env order."""
        parts = self._all("step", self._slices(self._actions))
        obs, rewards, dones, infos = zip(*parts)
        return (
            np.concatenate(obs),
            np.concatenate(rewards),
            np.concatenate(dones),
            [info for part in infos for info in part],
        )

    def close(self) -> None:
        """Close every shard; a worker that does not answer within 10 s is terminated."""
        if self.closed:
            return
        self.closed = True
        for pipe in self.pipes:
            try:
                pipe.send(("close", None))
            except (BrokenPipeError, OSError):
                pass
        for proc in self.procs:
            proc.join(10.0)
            if proc.is_alive():
                proc.terminate()
        for pipe in self.pipes:
            pipe.close()
        if hasattr(self, "local"):
            self.local.close()

    def _picked(self, values: list[Any], indices: VecEnvIndices) -> list[Any]:
        return [values[i] for i in self._get_indices(indices)]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """An attribute of the sub-envs `indices` (all by default)."""
        return self._picked(
            [v for part in self._all("get_attr", [attr_name] * len(self.bounds)) for v in part], indices
        )

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set an attribute of the sub-envs `indices` (all by default)."""
        chosen = set(self._get_indices(indices))
        local = [[i - lo for i in range(lo, hi) if i in chosen] for lo, hi in self.bounds]
        self._all("set_attr", [(attr_name, value, part) for part in local])

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        """Call a method of the sub-envs (every shard runs it; the answers of `indices` are returned)."""
        parts = self._all("env_method", [(method_name, method_args, method_kwargs)] * len(self.bounds))
        return self._picked([v for part in parts for v in part], indices)

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        """Whether the sub-envs carry `wrapper_class`."""
        parts = self._all("env_is_wrapped", [wrapper_class] * len(self.bounds))
        return self._picked([v for part in parts for v in part], indices)
