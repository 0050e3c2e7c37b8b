"""notebooks/country_distributions.ipynb: executed on pipeline outputs built in a temporary root, and as committed.

MPLBACKEND=Agg is set as the Makefile sets it: the notebook must still render real PNG figures (not the text
`<Figure size ...>` an Agg figure passed to display() gives).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import nbformat
import pandas as pd
import pytest
from nbclient import NotebookClient

from pipelines.common import REPO_ROOT
from pipelines.distribution import compute_distribution

NOTEBOOK = REPO_ROOT / "notebooks/country_distributions.ipynb"
COLUMNS = ["text", "category", "source", "country", "count"]
TWO_COUNTRIES = [("a street lamp", "street_lamp", "osm", "FI", 6), ("a bench", "bench", "osm", "FI", 2),
                 ("a traffic cone", "traffic_cone", "images", "JP", 4), ("a street lamp", "street_lamp", "images", "JP", 1)]


def _outputs(nb: nbformat.NotebookNode) -> list[dict]:
    """Every output of every code cell."""
    return [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]


def _text(nb: nbformat.NotebookNode) -> str:
    """All stream and text/plain output of the notebook, concatenated (a figure's text/plain twin left out)."""
    return "".join(o.get("text", "") + ("" if "image/png" in o.get("data", {}) else o.get("data", {}).get("text/plain", ""))
                   for o in _outputs(nb))


def _pngs(nb: nbformat.NotebookNode) -> list[str]:
    """The base64 image/png payloads among the notebook's outputs."""
    return [o["data"]["image/png"] for o in _outputs(nb) if "image/png" in o.get("data", {})]


def _execute(rows: list[tuple], root: Path, monkeypatch: pytest.MonkeyPatch) -> nbformat.NotebookNode:
    """Write a distribution and a pool from `rows` under `root`, then execute the notebook on them."""
    desc = pd.DataFrame(rows, columns=COLUMNS)
    (root / "data/distribution").mkdir(parents=True)
    (root / "data/pool").mkdir(parents=True)
    compute_distribution(desc, ["osm", "images"]).to_parquet(root / "data/distribution/distribution.parquet")
    pool = pd.DataFrame({"description_id": ["p0", "p1"], "cluster_id": [0, 1], "text": ["a street lamp", "a traffic cone"],
                         "category": ["street_lamp", "traffic_cone"], "members": [["a street lamp", "a street light"],
                                                                                  ["a traffic cone"]],
                         "n_members": [2, 1], "sources": [["osm"], ["images"]],
                         "country_counts": ['{"FI": 6, "JP": 1}', '{"JP": 4}'], "count": [7, 4]})
    pool.to_parquet(root / "data/pool/pool.parquet")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    monkeypatch.setenv("CURBSIDE_ROOT", str(root))
    monkeypatch.setenv("MPLBACKEND", "Agg")  # as the Makefile exports it
    # The venv's interpreter must run the kernel: put its bin first so "python3" resolves to it.
    monkeypatch.setenv("PATH", os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"])
    NotebookClient(nb, timeout=120, kernel_name="python3", resources={"metadata": {"path": str(root)}}).execute()
    return nb


def test_notebook_renders_png_figures_for_two_countries(tmp_path, monkeypatch):
    nb = _execute(TWO_COUNTRIES, tmp_path, monkeypatch)
    out = _text(nb)
    assert "['FI', 'JP']" in out and "[0] 'a street lamp'" in out and "- a street light" in out
    assert "JP most over-represented vs global" in out and "Only one country" not in out
    pngs = _pngs(nb)
    assert len(pngs) == 2, "one per-country chart and one global-versus-country chart"
    assert all(len(p) > 2000 for p in pngs), "tiny PNG payloads: the figures are empty"
    assert "<Figure size" not in out


def test_notebook_with_one_country_says_there_is_nothing_to_compare(tmp_path, monkeypatch):
    nb = _execute([r for r in TWO_COUNTRIES if r[3] == "FI"], tmp_path, monkeypatch)
    out = _text(nb)
    assert "countries: ['FI']" in out
    assert "Only one country is present (FI)" in out and "over-represented" not in out
    assert len(_pngs(nb)) == 1, "the per-country chart only: no empty comparison chart"
    assert "<Figure size" not in out


def test_committed_notebook_is_executed_with_png_figures():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code and all(c.get("execution_count") for c in code), "commit the notebook executed (docs/pipelines.md)"
    assert not [o for o in _outputs(nb) if o.get("output_type") == "error"]
    assert _pngs(nb) and "<Figure size" not in _text(nb)
    assert str(REPO_ROOT) not in _text(nb) and "/tmp/" not in _text(nb), "no machine-specific paths in outputs"
