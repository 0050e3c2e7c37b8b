"""Shared fixtures for the training tests."""

from __future__ import annotations

import pytest

from tests.street import street


@pytest.fixture(scope="session")
def spec() -> dict:
    """The hand-built straight-street scene spec (tests/street.py)."""
    return street()
