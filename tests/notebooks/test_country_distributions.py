"""Execute notebooks/country_distributions.ipynb on pipeline outputs built in a temporary root."""

from __future__ import annotations

import os
import sys

import nbformat
import pandas as pd
from nbclient import NotebookClient

from pipelines.common import REPO_ROOT
from pipelines.distribution import compute_distribution


def test_country_distributions_notebook_runs(tmp_path, monkeypatch):
    desc = pd.DataFrame(
        [("a street lamp", "street_lamp", "osm", "FI", 6), ("a bench", "bench", "osm", "FI", 2),
         ("a traffic cone", "traffic_cone", "images", "JP", 4), ("a street lamp", "street_lamp", "images", "JP", 1)],
        columns=["text", "category", "source", "country", "count"])
    (tmp_path / "data/distribution").mkdir(parents=True)
    (tmp_path / "data/pool").mkdir(parents=True)
    compute_distribution(desc, ["osm", "images"]).to_parquet(tmp_path / "data/distribution/distribution.parquet")
    pool = pd.DataFrame({"description_id": ["p0", "p1"], "cluster_id": [0, 1], "text": ["a street lamp", "a traffic cone"],
                         "category": ["street_lamp", "traffic_cone"], "members": [["a street lamp", "a street light"],
                                                                                  ["a traffic cone"]],
                         "n_members": [2, 1], "sources": [["osm"], ["images"]],
                         "country_counts": ['{"FI": 6, "JP": 1}', '{"JP": 4}'], "count": [7, 4]})
    pool.to_parquet(tmp_path / "data/pool/pool.parquet")
    nb = nbformat.read(REPO_ROOT / "notebooks/country_distributions.ipynb", as_version=4)
    monkeypatch.setenv("CURBSIDE_ROOT", str(tmp_path))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    # The venv's interpreter must run the kernel: put its bin first so "python3" resolves to it.
    monkeypatch.setenv("PATH", os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"])
    NotebookClient(nb, timeout=120, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    out = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []))
    assert "['FI', 'JP']" in out and "[0] 'a street lamp'" in out and "- a street light" in out
    assert any(o.get("output_type") == "display_data" for c in nb.cells for o in c.get("outputs", []))
