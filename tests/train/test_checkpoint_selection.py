"""benchmarks/checkpoint_selection.py: which of a run's checkpoints it scores."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _selection_module():
    spec = importlib.util.spec_from_file_location(
        "checkpoint_selection", ROOT / "benchmarks" / "checkpoint_selection.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_checkpoints_every_takes_the_save_nearest_each_multiple(tmp_path: Path) -> None:
    checkpoints = tmp_path / "checkpoints"
    checkpoints.mkdir()
    # SB3 saves a few steps past each multiple of its save frequency; the 5M mark has two candidates and a stray file.
    for steps in (475_008, 500_032, 525_056, 999_936, 1_000_000, 4_992_000, 5_017_600, 5_000_128, 250_000):
        (checkpoints / f"policy_{steps}_steps.zip").write_bytes(b"")
    (checkpoints / "policy_final.zip").write_bytes(b"")
    chosen = _selection_module().checkpoints_every(tmp_path, 500_000)
    assert sorted(chosen) == [500_032, 1_000_000, 5_000_128]
    assert chosen[1_000_000].name == "policy_1000000_steps.zip"


def test_checkpoints_every_skips_marks_with_no_save_near_them(tmp_path: Path) -> None:
    checkpoints = tmp_path / "checkpoints"
    checkpoints.mkdir()
    for steps in (300_000, 760_000):  # 200k and 240k away from 500k and 1M: no checkpoint stands for either
        (checkpoints / f"policy_{steps}_steps.zip").write_bytes(b"")
    assert _selection_module().checkpoints_every(tmp_path, 500_000) == {}
