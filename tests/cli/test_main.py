"""The `curbside` command: version, help at every level, fast start."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from curbside import __version__
from curbside.cli.main import app

runner = CliRunner()
REPO = Path(__file__).resolve().parents[2]
CATALOG_COMMANDS = ["build", "query", "show", "stats", "export", "validate", "contact-sheet"]


def test_version() -> None:
    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0
    assert res.stdout.strip() == f"curbside {__version__}"


@pytest.mark.parametrize("args", [[], ["catalog"], ["scenes"], ["sim"], ["pool"]])
def test_help_at_group_level(args: list[str]) -> None:
    res = runner.invoke(app, [*args, "--help"])
    assert res.exit_code == 0, res.output
    assert "Usage" in res.stdout
    if args == ["catalog"]:
        for cmd in CATALOG_COMMANDS:
            assert cmd in res.stdout


@pytest.mark.parametrize("cmd", CATALOG_COMMANDS)
def test_help_of_every_catalog_command(cmd: str) -> None:
    res = runner.invoke(app, ["catalog", cmd, "--help"])
    assert res.exit_code == 0, res.output
    assert "Usage" in res.stdout
    if cmd != "contact-sheet":
        assert "--catalog" in res.stdout


def test_help_does_not_import_heavy_libraries() -> None:
    code = (
        "import sys; from curbside.cli.main import app; "
        "print(','.join(m for m in ('torch', 'sentence_transformers', 'trimesh', 'pybullet') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
