"""Shared fixtures for the training tests."""

from __future__ import annotations

import pytest

from sim.tasks.toy_scene import straight_street


@pytest.fixture(scope="session")
def spec() -> dict:
    """The hand-built straight-road scene spec."""
    return straight_street()
