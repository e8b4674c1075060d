"""Time-series plots written to PNG."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_time_series"]


def plot_time_series(
    path: str | Path, time: np.ndarray, series: dict[str, np.ndarray], *, ylabel: str, title: str
) -> Path:
    """Plot each named series against time [s] into a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.0, 4.0), dpi=120)
    for name, y in series.items():
        ax.plot(time, y, label=name)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    from flexparcel.viz.consignment import save_figure

    return save_figure(fig, path)
