"""Shared fixtures for the simulator tests."""

from __future__ import annotations

import pytest

from tests.street import street


@pytest.fixture(scope="session")
def spec() -> dict:
    """The hand-built straight-street scene spec (tests/street.py; no generator needed)."""
    return street()


@pytest.fixture(scope="session")
def random_trace():
    """trace(env, seed, steps): reset(seed), then seeded random actions; observations with rewards appended."""
    import numpy as np

    def trace(env, seed: int, steps: int) -> list:
        obs, _ = env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        out = [obs]
        for _ in range(steps):
            obs, r, term, trunc, _ = env.step(rng.uniform(-1, 1, 2))
            out.append(np.append(obs, r))
            if term or trunc:
                break
        return out

    return trace
