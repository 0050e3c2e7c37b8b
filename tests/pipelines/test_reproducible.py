"""`dvc repro` in a fresh copy reproduces the committed dvc.lock files byte for byte, and stages die with dvc.

The copy holds the working tree's files (tracked and untracked-not-ignored, as a fresh clone of a commit of this
tree would), committed into a new git repository. Both pipelines run (dvc.yaml and retrieval/dvc.yaml); the
committed lock files record every output's md5, so a clean `git status` afterwards means every output came out
byte-identical to the run that wrote the lock. A forced re-run of the stages with float math (embed, cluster,
score, curate) must then leave the tree clean again: a second run in the same place gives the same bytes.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from pipelines.common import REPO_ROOT

VENV_BIN = Path(sys.executable).parent


def _env() -> dict[str, str]:
    """The stage environment: the venv first on PATH (dvc.yaml says `python`), offline hubs, no telemetry."""
    env = dict(
        os.environ,
        PATH=f"{VENV_BIN}{os.pathsep}{os.environ['PATH']}",
        HF_HUB_OFFLINE="1",
        TRANSFORMERS_OFFLINE="1",
        DVC_NO_ANALYTICS="1",
    )
    env.pop("DVC_ROOT", None)
    return env


def _git(repo: Path, *args: str) -> str:
    """Run git in `repo` and return its stdout."""
    return subprocess.run(["git", "-C", str(repo), *args], check=True, capture_output=True, text=True).stdout


def _dvc(repo: Path, *args: str) -> subprocess.CompletedProcess:
    """Run the venv's dvc in `repo`; fails the test with dvc's output when it fails."""
    res = subprocess.run(
        [str(VENV_BIN / "dvc"), *args], cwd=repo, env=_env(), capture_output=True, text=True, check=False, timeout=900
    )
    assert res.returncode == 0, f"dvc {' '.join(args)} failed:\n{res.stdout}\n{res.stderr}"
    return res


def _dirty(repo: Path) -> str:
    """`git status --porcelain` plus the diff of the lock files, empty when the tree is clean."""
    status = _git(repo, "status", "--porcelain")
    return status and status + _git(repo, "diff", "--", "dvc.lock", "retrieval/dvc.lock")


@pytest.fixture(scope="module")
def fresh_copy(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """A new git repository holding this tree's files, after `dvc repro --all-pipelines`; (path, dvc's stdout)."""
    repo = tmp_path_factory.mktemp("fresh") / "curbside"
    files = _git(REPO_ROOT, "ls-files", "-z", "--cached", "--others", "--exclude-standard").split("\0")
    for rel in filter(None, files):
        src = REPO_ROOT / rel
        if src.is_file():
            (repo / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, repo / rel)
    _git(repo, "init", "-q")
    _git(repo, "add", "-A")
    _git(repo, "-c", "user.name=test", "-c", "user.email=test@example.com", "commit", "-q", "-m", "fresh copy")
    return repo, _dvc(repo, "repro", "--all-pipelines").stdout


def test_dvc_repro_in_a_fresh_copy_leaves_the_tree_clean(fresh_copy):
    repo, out = fresh_copy
    assert "Running stage 'embed'" in out and "Running stage 'retrieval/dvc.yaml:curate'" in out  # it did run
    dirty = _dirty(repo)
    assert not dirty, (
        "dvc repro changed committed files: outputs differ from the run that wrote the lock, or the "
        f"lock is stale (run `dvc repro --all-pipelines` and commit the lock files):\n{dirty}"
    )


def test_forced_rerun_gives_byte_identical_outputs(fresh_copy):
    repo, _ = fresh_copy
    lock = yaml.safe_load((repo / "dvc.lock").read_text())["stages"]
    before = {o["path"]: o["md5"] for st in ("embed", "cluster") for o in lock[st]["outs"]}
    assert before["data/embed/embeddings.parquet"] and before["data/pool/pool.parquet"]
    for stage in ("embed", "cluster", "retrieval/dvc.yaml:score", "retrieval/dvc.yaml:curate"):
        _dvc(repo, "repro", "--force", "--single-item", stage)
    dirty = _dirty(repo)
    assert not dirty, f"a forced re-run wrote different bytes:\n{dirty}"


def test_parquet_writer_is_byte_stable(tmp_path):
    """Equal frames give equal files, and no pandas metadata (which names the pandas version) is stored."""
    import pandas as pd
    import pyarrow.parquet as pq

    from kernel.reproducible import write_frame

    df = pd.DataFrame({"text": ["b", "a"], "members": [["x"], ["y", "z"]], "count": [2, 1]})
    a, b = write_frame(df, tmp_path / "a.parquet"), write_frame(df.copy(), tmp_path / "b.parquet")
    assert a.read_bytes() == b.read_bytes()
    assert pq.read_schema(a).metadata is None or b"pandas" not in pq.read_schema(a).metadata
    assert pd.read_parquet(a)["members"].map(list).tolist() == [["x"], ["y", "z"]]


def _alive(pid: int) -> bool:
    """Whether `pid` exists and is not a zombie."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state not in ("Z", "X")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl(PR_SET_PDEATHSIG) is Linux-only")
def test_stage_dies_when_its_parent_is_killed(tmp_path):
    """SIGKILL the process that launched a stage (dvc's role): the stage must not keep running as an orphan."""
    # The stage's params file is a FIFO nobody writes: the stage blocks reading it, so it can only end if killed.
    fifo = tmp_path / "params.yaml"
    os.mkfifo(fifo)
    launcher = (
        "import subprocess, sys, time; "
        f"p = subprocess.Popen([sys.executable, '-m', 'pipelines.osm', '--params', {str(fifo)!r}], "
        f"cwd={str(REPO_ROOT)!r}); print(p.pid, flush=True); time.sleep(600)"
    )
    parent = subprocess.Popen([sys.executable, "-c", launcher], stdout=subprocess.PIPE, text=True, env=_env())
    child = -1
    try:
        child = int(parent.stdout.readline())
        time.sleep(3.0)  # past interpreter start-up: the stage is waiting on its params
        assert _alive(child), "the stage ended before its parent was killed: the test proves nothing"
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 10
        while _alive(child) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _alive(child), "the stage kept running after its parent was SIGKILLed"
    finally:
        if parent.poll() is None:
            parent.kill()
        if child > 0 and _alive(child):
            os.kill(child, signal.SIGKILL)
