"""Plots the paper-table benchmarks share: our bars beside the paper's, one panel per block or runway."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


def beside_paper(
    ax: Any,
    labels: list[str],
    ours: list[float],
    paper: list[float] | tuple[float, ...],
    *,
    ours_label: str,
    paper_label: str,
    title: str,
    err: list[float] | None = None,
) -> None:
    """Grouped bars on `ax`: ours (blue, with error bars when given) beside the paper's (grey), per label."""
    pos = np.arange(len(labels))
    ax.bar(pos - 0.2, ours, 0.4, yerr=err, label=ours_label, color="#3b7dd8")
    ax.bar(pos + 0.2, paper, 0.4, label=paper_label, color="#bbbbbb")
    ax.set_xticks(pos, labels, fontsize=8)
    ax.set_title(title)


def save_panels(fig: Any, axes: Any, ylabel: str, path: Path) -> None:
    """Label the first panel, add the legend, and write the figure to `path`."""
    import matplotlib.pyplot as plt

    axes[0].set_ylabel(ylabel)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
