"""DVC stage processes print one summary line each: no third-party progress bars or banners.

The stages run as dvc runs them, in a subprocess with the suite's environment minus the variables conftest sets
to quiet Hugging Face, so the stage code itself must do it.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import yaml

from pipelines.common import REPO_ROOT

NOISE = ("Loading weights", "it/s]", "pybullet build time", "%|")


def _run(args: list[str], cwd: Path) -> str:
    """Run `python -m <args>` in `cwd` as dvc would; returns stdout + stderr, failing on a non-zero exit."""
    env = {k: v for k, v in os.environ.items() if k not in ("HF_HUB_DISABLE_PROGRESS_BARS", "TQDM_DISABLE")}
    env["PYTHONPATH"] = str(REPO_ROOT)
    res = subprocess.run(
        [sys.executable, "-m", *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=300, check=False
    )
    assert res.returncode == 0, res.stdout + res.stderr
    return res.stdout + res.stderr


def _assert_one_summary_line(out: str, stage: str) -> None:
    """The output is exactly one line, `<stage>: <summary>`, with no third-party noise."""
    lines = out.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{stage}: "), out
    assert not [n for n in NOISE if n in out], out


def test_embed_stage_prints_one_summary_line(tmp_path):
    pd.DataFrame(
        {
            "text": ["a green bench", "a street lamp", "a green bench"],
            "category": ["bench", "street_lamp", "bench"],
            "source": ["osm"] * 3,
            "country": ["FI"] * 3,
            "count": [1, 2, 3],
        }
    ).to_parquet(tmp_path / "d.parquet")
    (tmp_path / "params.yaml").write_text(yaml.safe_dump({"embed": {"descriptions": "d.parquet", "out_dir": "emb"}}))
    out = _run(["pipelines.embed", "--params", "params.yaml"], tmp_path)
    _assert_one_summary_line(out, "embed")
    assert "texts_embedded=2" in out and (tmp_path / "emb" / "embeddings.parquet").exists()


def test_retrieval_stages_print_one_summary_line_each(tmp_path):
    params = yaml.safe_load((REPO_ROOT / "retrieval" / "params.yaml").read_text())
    params["source"]["limit"] = 1
    params["render"]["n_views"] = 4
    (tmp_path / "params.yaml").write_text(yaml.safe_dump(params))
    root = tmp_path / "root"
    for stage in ("normalise", "render", "score", "curate"):
        out = _run(
            ["retrieval.stages", stage, "--params", str(tmp_path / "params.yaml"), "--root", str(root)], REPO_ROOT
        )
        _assert_one_summary_line(out, stage)
    assert "1 assets written, 0 rejected" in out
    assert sorted(p.stem for p in (root / "catalog_tables").glob("*.parquet")) == [
        "assets",
        "descriptions",
        "embeddings",
        "matches",
        "meta",
        "rejections",
        "views",
    ]
