"""ar_fusion.png, in the style of the paper's Fig. 9: what the safety-driven fusion did during attack
response. Top: D_MSF, D_LD, the fused d and the physical D; middle: the two Kalman gains; bottom: the
heading relative to the lane that the fused pose carried."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from testbed.loop import TickRecord


def has_fusion(rows: Sequence[TickRecord]) -> bool:
    """True when any row carries a fused deviation (an LD3 run that reached attack response)."""
    return any(r.fused_dev is not None for r in rows)


def save_fusion_plot(path: Path, rows: Sequence[TickRecord], *, straddle_dev: float, title: str) -> None:
    """The AR rows of a run (those with a fused deviation) as the three panels of the module docstring."""
    ar = [r for r in rows if r.fused_dev is not None]
    if not ar:
        raise ValueError("no attack-response rows with fusion internals to plot")

    def col(name: str) -> np.ndarray:
        return np.array([np.nan if getattr(r, name) is None else getattr(r, name) for r in ar], dtype=float)

    t = col("t")
    fig = Figure(figsize=(8, 8))
    ax_d, ax_k, ax_h = fig.subplots(3, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2, 1.2]})
    ax_d.axhspan(-straddle_dev, straddle_dev, color="0.93", label="no lane straddle")
    ax_d.plot(t, col("msf_dev"), color="tab:red", ls="--", label="D_MSF")
    ax_d.plot(t, col("ld_dev"), color="tab:green", label="D_LD")
    ax_d.plot(t, col("fused_dev"), color="k", lw=1.8, label="fused d")
    ax_d.plot(t, col("phys_dev"), color="tab:blue", lw=1.2, label="physical D")
    ax_d.set_ylabel("lateral deviation (m, + left)")
    ax_d.legend(loc="best", fontsize=8, ncols=2)
    ax_d.grid(alpha=0.3)
    ax_d.set_title(title)
    ax_k.plot(t, col("k_msf"), color="tab:red", ls="--", label="Kalman gain MSF")
    ax_k.plot(t, col("k_ld"), color="tab:green", label="Kalman gain LD")
    ax_k.set_ylim(0.0, 1.0)
    ax_k.set_ylabel("gain")
    ax_k.legend(loc="best", fontsize=8)
    ax_k.grid(alpha=0.3)
    ax_h.plot(t, col("heading_used"), color="tab:orange")
    ax_h.set_ylabel("fused heading\nvs lane (rad)")
    ax_h.set_xlabel("time (s)")
    ax_h.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
