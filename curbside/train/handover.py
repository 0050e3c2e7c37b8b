"""The worker side of a ShardedVectorEnv's hand-over, and the primitives both sides use (`curbside.train.sharded`).

Each worker process runs `serve`: it waits for its `go` semaphore, carries out the command (`run_command`: a step
on the actions in the shared arrays, or a command read from its pipe) and replies (`reply`): observations, rewards
and flags in the shared arrays (`Shared`), a step's infos pickled into its shared buffer, anything else through its
pipe (`hand_over`). Both sides wait by polling their semaphore before blocking on it (`wait_for`). Why:
`docs/vector_envs.md`.
"""

from __future__ import annotations

import multiprocessing as mp
import pickle
import time
import traceback
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from multiprocessing.reduction import ForkingPickler
from typing import Any

import gymnasium as gym
import numpy as np


def _step_one(env: gym.Env, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
    obs, reward, terminated, truncated, info = env.step(action)
    if terminated or truncated:
        final_obs, final_info = obs, info
        obs, reset_info = env.reset()
        info = {"final_info": final_info, "final_obs": final_obs, **reset_info}
    return obs, float(reward), bool(terminated), bool(truncated), info


SPIN_S = 0.002  # seconds a waiting side polls its semaphore before blocking on it
# Messages up to this size are sent before the semaphore is released (the receiver finds them whole); a larger one
# after, as the sender blocks once the socket's buffer (~90 KB of data here) fills, and the receiver only reads
# after taking the semaphore: a 4-env shard's step infos with camera final_obs, or frames from call("render").
INLINE_BYTES = 16_384


def hand_over(pipe: Connection, sem: Any, message: Any) -> None:
    """Send `message` through `pipe` and release `sem` for the receiver, in the order that cannot deadlock."""
    data = ForkingPickler.dumps(message)
    if len(data) <= INLINE_BYTES:
        pipe.send_bytes(data)
        sem.release()
    else:
        sem.release()
        pipe.send_bytes(data)


def wait_for(sem: Any, spin: float, alive: Callable[[], bool], poll: float = 1.0) -> None:
    """Take `sem`, polling it for up to `spin` seconds (no syscall, the core stays hot) before blocking on it;
    EOFError when `alive()` turns false while blocked (the other side died)."""
    if spin > 0.0:
        deadline = time.perf_counter() + spin
        while time.perf_counter() < deadline:
            if sem.acquire(False):
                return
    while not sem.acquire(timeout=poll):
        if not alive():
            raise EOFError("the other side of a ShardedVectorEnv hand-over died")


class Shared:
    """The arrays every process of a ShardedVectorEnv maps: per env its observation, action, reward and flags; per
    worker its command word, its reply word (the infos' size) and a buffer for its step infos. Built in the parent, rebuilt from the same
    raw buffers in a worker (`views`)."""

    def __init__(self, ctx: Any, n: int, workers: int, obs_space: gym.spaces.Box, act_space: gym.Space) -> None:
        self.spec = {
            "obs": ((n, *obs_space.shape), np.dtype(obs_space.dtype).str),
            "rewards": ((n,), "<f8"),
            "terms": ((n,), "|b1"),
            "truncs": ((n,), "|b1"),
            "command": ((workers,), "<i8"),
            "reply": ((workers,), "<i8"),
            "infos": ((workers, INLINE_BYTES), "|u1"),
        }
        if isinstance(act_space, gym.spaces.Box):  # other action spaces travel through the pipe
            self.spec["actions"] = ((n, *act_space.shape), np.dtype(act_space.dtype).str)
        self.raw = {
            k: ctx.RawArray("b", int(np.prod(shape)) * np.dtype(dt).itemsize) for k, (shape, dt) in self.spec.items()
        }

    def views(self) -> dict[str, np.ndarray]:
        """numpy arrays over the shared buffers (call in the process that uses them)."""
        return {k: np.frombuffer(self.raw[k], dtype=dt).reshape(shape) for k, (shape, dt) in self.spec.items()}


def run_command(envs: Sequence[gym.Env], arrays: dict[str, np.ndarray], lo: int, command: str, data: Any) -> Any:
    """Carry out one command on a shard's envs lo.. (observations, and a step's rewards and flags, written into the
    shared `arrays`); the reply's payload (a step's: its infos)."""
    obs_out = arrays["obs"][lo : lo + len(envs)]
    if command == "step":
        infos = []
        rewards, terms, truncs = arrays["rewards"], arrays["terms"], arrays["truncs"]
        # A copy: the parent writes the next step's actions into the shared array while an env may keep this one.
        actions = arrays["actions"][lo : lo + len(envs)].copy() if data is None else data
        for k, (env, action) in enumerate(zip(envs, actions)):
            obs_out[k], rewards[lo + k], terms[lo + k], truncs[lo + k], info = _step_one(env, action)
            infos.append(info)
        return infos
    if command == "reset":
        seeds, options = data
        infos = []
        for k, (env, seed) in enumerate(zip(envs, seeds)):
            obs_out[k], info = env.reset(seed=seed, options=options)
            infos.append(info)
        return infos
    if command == "get_attr":
        return [env.get_wrapper_attr(data) for env in envs]
    if command == "set_attr":
        name, values = data
        for env, value in zip(envs, values):
            env.set_wrapper_attr(name, value)
        return None
    name, args, kwargs = data  # "call"
    out = []
    for env in envs:
        fn = env.get_wrapper_attr(name)
        out.append(fn(*args, **kwargs) if callable(fn) else fn)
    return out


STEP, PIPE = 1, 0  # a worker's command word: step on the shared actions, or read the command from the pipe


def reply(pipe: Connection, sem: Any, arrays: dict[str, np.ndarray], w: int, status: str, payload: Any) -> None:
    """Worker `w`'s reply: a step's infos through its shared buffer when they fit, anything else through the pipe
    (the reply word tells the parent which: the infos' size, or -1)."""
    if status == "step":
        data = pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL)  # infos: 0.5 us where ForkingPickler takes 4
        if len(data) <= INLINE_BYTES:
            arrays["infos"][w, : len(data)] = np.frombuffer(data, dtype=np.uint8)
            arrays["reply"][w] = len(data)
            sem.release()
            return
        status = "ok"
    arrays["reply"][w] = -1
    hand_over(pipe, sem, (status, payload))


def serve(
    fns: list[Callable[[], gym.Env]], pipe: Connection, go: Any, done: Any, spin: float, shared: Shared, w: int, lo: int
) -> None:
    """Worker `w`, owning envs lo..lo + len(fns) - 1: observations, rewards and flags into the shared arrays, the
    rest back through its buffer or pipe."""
    envs: list[gym.Env] = []
    arrays = shared.views()
    try:
        envs = [fn() for fn in fns]
        reply(pipe, done, arrays, w, "ok", None)
        # The process that made the vector env, by its sentinel: under forkserver os.getppid() is the fork server,
        # which outlives a parent killed by SIGKILL.
        parent = mp.parent_process()
        alive = parent.is_alive if parent is not None else (lambda: True)
        while True:
            wait_for(go, spin, alive)
            # A small pipe message was sent before `go` was released: no wait.
            command, data = ("step", None) if arrays["command"][w] == STEP else pipe.recv()
            if command == "close":
                break
            payload = run_command(envs, arrays, lo, command, data)
            reply(pipe, done, arrays, w, "step" if command == "step" else "ok", payload)
    except (KeyboardInterrupt, EOFError):
        pass
    except Exception:  # the parent re-raises it with this traceback
        try:
            reply(pipe, done, arrays, w, "error", traceback.format_exc())
        except OSError:
            pass  # the parent is gone
    finally:
        for env in envs:
            env.close()
