"""Byte-reproducible stage outputs and quiet stage processes, shared by pipelines/ and retrieval/ DVC stages.

DVC records the md5 of every output in dvc.lock, so a stage that writes the same rows as different bytes dirties
the lock on every run. Parquet written here carries nothing that varies between runs or installs except the
writer's `created_by` string (pyarrow's version, which pyproject.toml bounds): no pandas metadata (it names the
pandas version), fixed compression, one row group, fixed page settings.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

PARQUET_OPTIONS: dict[str, Any] = {
    "compression": "snappy",
    "version": "2.6",
    "data_page_version": "1.0",
    "use_dictionary": True,
    "write_statistics": True,
    "row_group_size": 1 << 24,
    "write_page_index": False,
    "store_schema": True,
}


def write_parquet(table: Any, path: str | Path) -> Path:
    """Write a pyarrow Table with the fixed PARQUET_OPTIONS (its schema metadata kept as given), creating the folder."""
    import pyarrow.parquet as pq

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(table, p, **PARQUET_OPTIONS)
    return p


def write_frame(df: Any, path: str | Path) -> Path:
    """Write a pandas DataFrame as parquet without its index or pandas metadata: equal frames give equal bytes."""
    import pyarrow as pa

    return write_parquet(pa.Table.from_pandas(df, preserve_index=False).replace_schema_metadata(None), path)


def write_npz(arrays: dict[str, Any], path: str | Path) -> Path:
    """Write numpy arrays as an uncompressed .npz (np.load reads it) with fixed zip timestamps: equal arrays give
    equal bytes (np.savez stamps every member with the current time)."""
    import io
    import zipfile

    import numpy as np

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + ".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_STORED) as zf:
        for name in sorted(arrays):
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asanyarray(arrays[name]), allow_pickle=False)
            zf.writestr(zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0)), buf.getvalue())
    os.replace(tmp, p)
    return p


def quiet_third_party() -> None:
    """Silence third-party progress bars and advisories (Hugging Face Hub, transformers, tqdm) in this process."""
    os.environ.setdefault("HF_HUB_DISABLE_PROGRESS_BARS", "1")  # read by huggingface_hub and transformers at import
    os.environ.setdefault("TRANSFORMERS_NO_ADVISORY_WARNINGS", "1")
    os.environ.setdefault("TQDM_DISABLE", "1")  # tqdm reads TQDM_* defaults per bar (sentence-transformers' encode)
    os.environ.setdefault("TOKENIZERS_PARALLELISM", "false")
    if "transformers" in sys.modules:  # imported before this call: its flag was already read
        from transformers.utils import logging as hf_logging

        hf_logging.disable_progress_bar()
    if "huggingface_hub" in sys.modules:
        from huggingface_hub.utils import disable_progress_bars

        disable_progress_bars()
