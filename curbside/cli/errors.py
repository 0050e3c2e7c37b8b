"""One error style for the whole `curbside` command: one line naming the problem and the fix, on stderr.

Exit codes: 2 for bad usage or input (an unknown option value, a config key, a missing or corrupt file the user
named), 1 for a run that failed on good input. `--debug` (anywhere on the command line) or `CURBSIDE_DEBUG=1`
shows the full traceback instead. Commands raise the exceptions below (or ConfigError / ValueError for bad
values); `run` maps every exception to its line and code, so no command needs its own try/except.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import click
import typer

if TYPE_CHECKING:  # typer >= 0.20 builds its commands on its vendored click
    from typer._click.core import Command as _TyperCommand

DEBUG_ENV = "CURBSIDE_DEBUG"
MAX_LINE = 600  # characters of an error line

try:  # typer >= 0.20 parses with its own vendored copy of click: its BadParameter is not a click.ClickException
    from typer._click.exceptions import ClickException as _TyperClickException

    _CLICK_ERRORS: tuple[type[click.ClickException | _TyperClickException], ...] = (
        click.ClickException,
        _TyperClickException,
    )
except ImportError:
    _CLICK_ERRORS = (click.ClickException,)


class UsageError(Exception):
    """Bad input from the user: the message names the problem and the fix (exit code 2)."""

    exit_code = 2


class RunError(Exception):
    """A run that failed on valid input: the message says what failed and what to try (exit code 1)."""

    exit_code = 1


def fail(message: str, code: int = 2) -> typer.Exit:
    """Print `message` as the one error line and return the Exit to raise (code 2: bad input, 1: failed run)."""
    echo_error(message)
    return typer.Exit(code)


def echo_error(message: str) -> None:
    """Write `error: message` to stderr as one line (no rich markup interpretation of the message)."""
    from rich.console import Console
    from rich.text import Text

    line = " ".join(str(message).split())  # one line, whatever the exception's text held
    while line.startswith("error: "):  # a message that already carries the prefix
        line = line[len("error: ") :]
    if len(line) > MAX_LINE:  # a message that quotes a whole input: the start says what is wrong
        line = f"{line[:MAX_LINE]}... ({len(line) - MAX_LINE} more characters)"
    Console(stderr=True, soft_wrap=True).print(Text.assemble(("error: ", "bold red"), line), highlight=False)


def debug_enabled(argv: Sequence[str] | None = None) -> bool:
    """Whether tracebacks were asked for (`--debug` in argv or CURBSIDE_DEBUG set to a true value)."""
    argv = sys.argv[1:] if argv is None else argv
    return "--debug" in argv or os.environ.get(DEBUG_ENV, "").lower() in ("1", "true", "yes")


def classify(exc: BaseException) -> tuple[str, int]:
    """The one line and exit code for an exception raised by a command."""
    from kernel.config import ConfigError

    name = type(exc).__name__
    text = str(exc) or name
    if isinstance(exc, (UsageError, RunError)):
        return text, exc.exit_code
    if isinstance(exc, ConfigError):
        return text, 2
    if isinstance(exc, ModuleNotFoundError) and exc.name:
        from curbside.cli.extras import extra_of, missing_line

        extra = extra_of(exc.name)
        if extra is not None:
            return missing_line(extra, exc.name.split(".")[0]), 2
    if isinstance(exc, json.JSONDecodeError):
        return (
            f"invalid JSON ({exc.msg} at line {exc.lineno} column {exc.colno}); pass a JSON object such as '{{\"key\": 1}}'",
            2,
        )
    if isinstance(exc, FileNotFoundError):
        return f"{exc.filename or text}: no such file or directory; check the path", 2
    if isinstance(exc, NotADirectoryError):
        return f"{exc.filename or text}: a part of this path is a file, not a folder; choose another path", 2
    if isinstance(exc, FileExistsError):
        return f"{exc.filename or text} already exists and is not a folder; choose another path", 2
    if isinstance(exc, KeyError):
        return (
            f"missing key {exc.args[0]!r} in the input (a file or config lacks it; compare it with the format "
            "the docs give)"
        ), 2
    if isinstance(exc, IsADirectoryError):
        return f"{exc.filename or text} is a directory; give a file path", 2
    if isinstance(exc, PermissionError):
        return f"{exc.filename or text}: permission denied; choose a writable path", 2
    if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EFBIG, errno.EDQUOT):
        where = f"{exc.filename}: " if exc.filename else ""
        return (
            f"{where}could not write: the disk is full or a file passes a size limit; free space or write "
            "elsewhere, then rerun"
        ), 1
    if isinstance(exc, (ValueError, TypeError)):
        return f"{text}", 2
    if isinstance(exc, MemoryError):
        return "out of memory; use a smaller input (fewer blocks, scenes or assets)", 1
    return f"{name}: {text} (rerun with --debug for the traceback)", 1


def empty_option(args: Sequence[str]) -> str | None:
    """The first option given an empty value (`--out ''` or `--out=`), if any: no option of curbside takes one."""
    for k, a in enumerate(args):
        if a == "--":
            return None
        if a.startswith("--") and a.endswith("=") and len(a) > 3:
            return a[:-1]
        if a.startswith("-") and len(a) > 1 and k + 1 < len(args) and args[k + 1] == "":
            return a
    return None


def run(command: click.Command | _TyperCommand, argv: Sequence[str] | None = None, prog_name: str = "curbside") -> int:
    """Run a click/typer command with the project's error style and return its exit code."""
    args = list(sys.argv[1:] if argv is None else argv)
    debug = debug_enabled(args)
    args = [a for a in args if a != "--debug"]
    if debug:
        os.environ[DEBUG_ENV] = "1"
    empty = empty_option(args)
    if empty is not None:
        # An empty path would mean the working directory (Path("") is "."): files would land where no one looks.
        echo_error(f"{empty} is empty; give it a value (see the command's --help)")
        return 2
    try:
        rv = command.main(args=args, prog_name=prog_name, standalone_mode=False)
    except click.exceptions.Exit as e:  # typer.Exit raised outside click's own handling
        return int(e.exit_code or 0)
    except _CLICK_ERRORS as e:
        # Usage errors as one line too: click's own three (usage, hint, error) repeat what --help says.
        ctx = getattr(e, "ctx", None)
        hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
        if e.format_message():  # empty for "no arguments: here is the help", already printed
            echo_error(f"{e.format_message()}{hint}")
        return int(e.exit_code)
    except click.Abort:
        echo_error("aborted")
        return 1
    except KeyboardInterrupt:
        echo_error("interrupted")
        return 130
    except BrokenPipeError:
        return 0
    except Exception as e:
        if debug:
            raise
        line, code = classify(e)
        echo_error(line)
        return code
    return int(rv) if isinstance(rv, int) else 0


CONFIG_EXAMPLE = '\'{"machine": "wheelchair", "horizon": 500}\''


def parse_config_json(config_json: str | None, option: str = "--config") -> dict:
    """The JSON object given to `option` as a dict ({} when absent); UsageError naming the problem otherwise."""
    if not config_json:
        return {}
    try:
        cfg = json.loads(config_json)
    except json.JSONDecodeError as e:
        raise UsageError(
            f"{option} is not valid JSON ({e.msg} at column {e.colno}); pass a JSON object such as {CONFIG_EXAMPLE}"
        ) from None
    if not isinstance(cfg, dict):
        raise UsageError(f"{option} must be a JSON object, got a JSON {type(cfg).__name__}; pass e.g. {CONFIG_EXAMPLE}")
    return cfg


@contextlib.contextmanager
def catalog_cli_errors(catalog: Path) -> Iterator[None]:
    """Map catalog failures to the CLI's error style: locked or unwritable -> exit 1 (wait or free space, retry),
    missing/corrupt/other -> 2."""
    from catalogs.reader import CatalogWriteFailed, catalog_errors
    from catalogs.schema import CatalogError, CatalogLocked

    try:
        with catalog_errors(catalog):  # DuckDB errors raised while reading (a damaged block) get the same words
            yield
    except (CatalogLocked, CatalogWriteFailed) as e:
        raise RunError(str(e)) from e
    except CatalogError as e:
        raise UsageError(str(e)) from e
