"""Helpers the test modules share: run the `curbside` command as its console script does, read its one error line,
list the modules a source file imports."""

from __future__ import annotations

import ast
from collections.abc import Sequence

import pytest


def cli(argv: Sequence[str], capture: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """Run `curbside ARGV` in-process through `curbside.cli.errors.run`, as the console script does.

    Returns (exit code, stdout, stderr) as read by `capture` (pytest's capsys, or capfd where a library writes
    to the file descriptors).
    """
    import typer

    from curbside.cli.errors import run
    from curbside.cli.main import app

    code = run(typer.main.get_command(app), list(argv))
    out, err = capture.readouterr()
    return code, out, err


def one_error_line(code: int, out: str, err: str, exit_code: int = 2) -> str:
    """The single `error: ...` line of a failed command (asserting the exit code, one line, no traceback)."""
    assert code == exit_code, (code, out, err)
    assert "Traceback" not in out + err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    return lines[0]


def absolute_imports(source: str) -> list[str]:
    """Every module `source` imports by absolute name (`import a.b`, `from a.b import c`), in order."""
    mods: list[str] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            mods += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            mods.append(node.module)
    return mods
