"""Plots (matplotlib, imported lazily)."""

__all__ = ["plot_time_series"]


def plot_time_series(*args, **kwargs):
    """See :func:`flexparcel.viz.plots.plot_time_series`."""
    from flexparcel.viz.plots import plot_time_series as _p

    return _p(*args, **kwargs)
