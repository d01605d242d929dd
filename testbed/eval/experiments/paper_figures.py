"""Figures of the paper report: the paper's value beside ours, as paired bars with their spread."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

Stat = tuple[float, float] | None
"""(mean, std), or None where there is no value."""


def paper_vs_ours(path: Path, title: str, labels: Sequence[str], paper: Sequence[Stat], ours: Sequence[Stat],
                  ylabel: str, reference: tuple[float, str] | None = None) -> None:
    """Paired bars per label (paper grey, ours blue) with ±std whiskers; a missing value leaves its bar out
    and is marked '–'; `reference` draws a horizontal line (value, legend text)."""
    if not (len(labels) == len(paper) == len(ours)):
        raise ValueError("labels, paper and ours must have one entry each")
    x = np.arange(len(labels))
    width = 0.38
    fig = Figure(figsize=(max(5.0, 0.75 * len(labels) + 2.0), 3.8), layout="constrained")
    ax = fig.subplots()
    for offset, values, colour, name in ((-width / 2, paper, "0.6", "paper"), (width / 2, ours, "tab:blue", "ours")):
        for xi, value in zip(x + offset, values, strict=True):
            if value is None:
                ax.text(xi, 0.0, "–", ha="center", va="bottom", fontsize=8, color=colour)
                continue
            ax.bar(xi, value[0], width, yerr=value[1], color=colour, capsize=2, edgecolor="none")
        ax.bar([], [], color=colour, label=name)
    if reference is not None:
        ax.axhline(reference[0], color="tab:red", lw=1, ls="--", label=reference[1])
    ax.set_xticks(x, list(labels), rotation=30, ha="right", fontsize=8)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110)
