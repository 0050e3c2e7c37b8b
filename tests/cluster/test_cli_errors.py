"""Executor options that cannot work fail as one line before any work (no Ray cluster is started here)."""

from __future__ import annotations

import pytest

from tests.helpers import cli, one_error_line


def test_unreachable_cluster_is_one_line_exit_2(capsys) -> None:
    ray = pytest.importorskip("ray")
    assert not ray.is_initialized()
    line = one_error_line(
        *cli(["sim", "eval", "--episodes", "1", "--executor", "ray", "--address", "127.0.0.1:1"], capsys)
    )
    assert "cannot reach a Ray cluster" in line and "ray start --head" in line


def test_a_bad_executor_lists_the_valid_ones(capsys) -> None:
    line = one_error_line(*cli(["scenes", "dataset", "--out", "x", "--executor", "slurm"], capsys))
    assert "local" in line and "process" in line and "ray" in line


def test_run_map_refuses_an_address_without_ray() -> None:
    from kernel.config import ConfigError
    from kernel.executors import run_map

    with pytest.raises(ConfigError, match="executor 'ray'"):
        list(run_map(abs, [1], executor="process", address="auto"))
    with pytest.raises(ConfigError, match="workers"):
        list(run_map(abs, [1], executor="process", workers=0))
