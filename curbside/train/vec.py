"""SB3's VecEnv over a Gymnasium VectorEnv, so SB3's algorithms train on `gymnasium.make_vec(..., "async")` workers
(or on any VectorEnv that resets in the same step, such as a batched env).

Gymnasium's vector envs return infos as one dict of arrays with `_key` masks, and with
`autoreset_mode=SAME_STEP` put the last observation and info of a finished episode under `final_obs` and
`final_info`; SB3 wants a list of per-env dicts with the last observation under `terminal_observation`. The
adapter translates, nothing more: the episodes, rewards and observations are the env's own (a test checks them
against SB3's SubprocVecEnv on the same seeds).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol, cast

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvStepReturn


class _WorkerVectorEnv(Protocol):
    """What Gymnasium's AsyncVectorEnv and SyncVectorEnv (and ShardedVectorEnv) add to a VectorEnv and the adapter
    calls: one seed per env, asynchronous steps, the sub-envs' attributes and methods."""

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]: ...

    def step_async(self, actions: Any) -> None: ...

    def step_wait(self) -> tuple[Any, Any, Any, Any, dict[str, Any]]: ...

    def get_attr(self, name: str) -> tuple[Any, ...]: ...

    def set_attr(self, name: str, values: Any) -> None: ...

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]: ...


def unbatch(info: dict[str, Any], n: int) -> list[dict[str, Any]]:
    """Per-env dicts of a Gymnasium vector info (values of env i where the key's `_key` mask holds)."""
    out: list[dict[str, Any]] = [{} for _ in range(n)]
    for key, value in info.items():
        if key.startswith("_"):
            continue
        mask = info.get(f"_{key}")
        parts = unbatch(value, n) if isinstance(value, dict) else value
        for i in range(n):
            if mask is None or mask[i]:
                v = parts[i]
                out[i][key] = v.item() if isinstance(v, np.generic) else v  # plain numbers, as one env gives
    return out


def single_thread_worker(fn: Callable[[], gym.Env]) -> Callable[[], gym.Env]:
    """`fn` run with BLAS/OpenMP limited to one thread in the worker: N workers on N cores must not spin extra
    threads against each other (measured: 368 -> 437 env steps/s for 2 PointNav workers on 2 cores)."""

    def make() -> gym.Env:
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
        return fn()

    return make


class VectorEnvAdapter(VecEnv):
    """An SB3 VecEnv stepping a Gymnasium VectorEnv created with `autoreset_mode=SAME_STEP`.

    `wrappers` names the wrapper classes every sub-env carries (for `env_is_wrapped`, which a Gymnasium
    VectorEnv cannot ask its workers).
    """

    def __init__(self, venv: gym.vector.VectorEnv, wrappers: Sequence[type] = ()) -> None:
        mode = venv.metadata.get("autoreset_mode")
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(
                f"the vector env must reset finished episodes in the same step (autoreset_mode="
                f"AutoresetMode.SAME_STEP, as SB3 expects), got {mode!r}"
            )
        self.venv = venv  # before VecEnv.__init__, which asks the sub-envs for their render mode
        self.wrappers = tuple(wrappers)
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None
        self._async = hasattr(venv, "step_async")

    def reset(self) -> Any:
        """Reset every env (with the seeds and options set by `seed` and `set_options`, used once)."""
        seeds = None if self._seeds == [None] * self.num_envs else list(self._seeds)
        if any(o != self._options[0] for o in self._options):
            raise ValueError(
                "the sub-envs were given different reset options; a Gymnasium vector env resets all "
                "its envs with one options dict: pass one dict to set_options"
            )
        obs, info = self._workers.reset(seed=seeds, options=self._options[0] or None)
        self.reset_infos = unbatch(info, self.num_envs)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        """Send the actions (the workers step while the caller goes on)."""
        if self._async:
            self._workers.step_async(actions)
        else:
            self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        """Observations, rewards, dones and per-env infos; a finished env's info holds its last observation."""
        if self._async:
            obs, rewards, terminated, truncated, info = self._workers.step_wait()
        else:
            obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        dones = np.logical_or(terminated, truncated)
        infos = unbatch(info, self.num_envs)
        for i in np.flatnonzero(dones).tolist():
            reset_info = infos[i]
            infos[i] = reset_info.pop("final_info", {})
            infos[i]["terminal_observation"] = reset_info.pop("final_obs")
            self.reset_infos[i] = reset_info
        for i, inf in enumerate(infos):
            inf["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])  # as SB3's own VecEnvs
        return obs, rewards, dones, infos

    def close(self) -> None:
        """Close the workers."""
        self.venv.close()

    @property
    def _workers(self) -> _WorkerVectorEnv:
        # Gymnasium's VectorEnv declares none of these; the envs adapted here have the ones each call site uses.
        return cast(_WorkerVectorEnv, self.venv)

    def _select(self, values: Sequence[Any], indices: VecEnvIndices) -> list[Any]:
        return [values[i] for i in self._get_indices(indices)]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """An attribute of the (wrapped) sub-envs; a VectorEnv without sub-env objects (a batched env) answers for
        all of them."""
        if not hasattr(self.venv, "get_attr"):
            return self._select([getattr(self.venv, attr_name)] * self.num_envs, indices)
        return self._select(self.venv.get_attr(attr_name), indices)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set an attribute of the sub-envs `indices` (all by default)."""
        chosen = set(self._get_indices(indices))
        if len(chosen) == self.num_envs:
            self._workers.set_attr(attr_name, value)
            return
        current = self._workers.get_attr(attr_name)
        self._workers.set_attr(attr_name, [value if i in chosen else current[i] for i in range(self.num_envs)])

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        """Call a method of the sub-envs (every worker runs it; the answers of `indices` are returned)."""
        return self._select(self._workers.call(method_name, *method_args, **method_kwargs), indices)

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        """Whether the sub-envs carry `wrapper_class` (as declared when the adapter was built)."""
        wrapped = any(issubclass(w, wrapper_class) for w in self.wrappers)
        return [wrapped] * len(list(self._get_indices(indices)))
