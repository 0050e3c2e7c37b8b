"""Bad input, round two: YAML that expands, values quoted whole in error lines, nested configs on the CLI."""

from __future__ import annotations

import json

import pytest

from kernel.config import ConfigError, excerpt, load_yaml
from tests.helpers import cli, one_error_line

BOMB = 'a: &a ["x","x","x","x","x","x","x","x","x"]\nb: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]\nc: [*b,*b,*b,*b,*b,*b,*b,*b]\n'


def test_yaml_aliases_are_refused_before_they_expand(tmp_path, capsys) -> None:
    f = tmp_path / "custom.yaml"
    f.write_text(BOMB)
    line = one_error_line(*cli(["scenes", "generate", "--from", str(f), "--out", str(tmp_path / "s.json")], capsys))
    assert "YAML alias *a at line 2" in line and len(line) < 300
    g = tmp_path / "exp.yaml"
    g.write_text(BOMB)
    line = one_error_line(*cli(["experiment", "run", str(g), "--budget", "smoke", "--root", str(tmp_path)], capsys))
    assert "YAML alias" in line
    assert not (tmp_path / "s.json").exists()


def test_unparsable_yaml_names_the_line() -> None:
    with pytest.raises(ConfigError, match=r"f.yaml is not valid YAML at line 3, column 2: expected .,. or .]."):
        load_yaml("a: 1\nb: [1, 2\nc: 3\n", "f.yaml")


def test_error_lines_quote_an_excerpt_not_the_whole_value(capsys) -> None:
    huge = "x" * 100_000
    assert len(excerpt(huge)) < 130 and excerpt("ok") == "'ok'"
    line = one_error_line(*cli(["sim", "eval", "--episodes", "1", "--config", json.dumps({"machine": huge})], capsys))
    assert len(line) <= 700 and "unknown machine" in line


def test_nested_machine_nan_is_one_line_not_a_crash(capsys) -> None:
    cfg = '{"scene": {"blocks": 1}, "machine": {"base": {"wheel_radius": NaN}}}'
    line = one_error_line(*cli(["sim", "eval", "--episodes", "1", "--config", cfg], capsys))
    assert "config.machine.base.wheel_radius must be a finite number" in line


def test_paths_through_files_and_bare_keys_are_bad_input_with_a_fix() -> None:
    from curbside.cli.errors import classify

    line, code = classify(NotADirectoryError(20, "Not a directory", "/tmp/file/sub"))
    assert code == 2 and "is a file, not a folder" in line
    line, code = classify(FileExistsError(17, "File exists", "/tmp/x"))
    assert code == 2 and "already exists" in line
    line, code = classify(KeyError("task"))
    assert code == 2 and line.startswith("missing key 'task'")


def test_an_error_line_never_repeats_its_prefix(capsys) -> None:
    from curbside.cli.errors import echo_error

    echo_error("error: no such thing")
    assert capsys.readouterr().err.strip() == "error: no such thing"


@pytest.mark.parametrize("seed", ["true", "100000000000000000000000", "-1", "'7'"])
def test_a_custom_scene_seed_must_be_an_integer_in_range(seed, tmp_path, capsys) -> None:
    f = tmp_path / "custom.yaml"
    f.write_text(f"seed: {seed}\nblocks: 1\n")
    line = one_error_line(*cli(["scenes", "generate", "--from", str(f), "--out", str(tmp_path / "s.json")], capsys))
    assert "seed must be an integer in [0, 2**32)" in line


def test_from_with_generator_options_is_refused(tmp_path, capsys) -> None:
    f = tmp_path / "custom.yaml"
    f.write_text("seed: 1\nblocks: 1\n")
    line = one_error_line(
        *cli(["scenes", "generate", "--from", str(f), "--blocks", "5", "--out", str(tmp_path / "s.json")], capsys)
    )
    assert "drop --blocks" in line


def test_an_empty_local_source_is_refused(tmp_path, capsys, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    line = one_error_line(
        *cli(["catalog", "ingest", "--source", "local:", "--catalog", str(tmp_path / "c.duckdb")], capsys)
    )
    assert "local: needs a folder" in line and not (tmp_path / "c.duckdb").exists()
