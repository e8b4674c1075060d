"""A 2-D picture of a clustered survey: classical MDS of the Gower distances.

Gower distances are not Euclidean, so no flat map preserves them; classical (Torgerson) MDS
gives the best rank-2 least-squares fit of the double-centred squared distances, enough to see
whether clusters separate. Matplotlib is imported inside :func:`plot_embedding` only.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from flexparcel.selection.clustering import NOISE, SurveyClustering

__all__ = ["classical_mds", "plot_embedding"]

# Above this size the two leading eigenpairs come from Lanczos (O(n^2) per iteration) instead of
# a full O(n^3) eigendecomposition.
_DENSE_EIGH_MAX = 800


def classical_mds(distances: np.ndarray, dim: int = 2) -> np.ndarray:
    """Classical MDS coordinates, shape (n, dim), in distance units (Gower: dimensionless).

    B = -1/2 J D^2 J with J the centring matrix; coordinates are the leading eigenvectors scaled
    by sqrt(eigenvalue) (negative eigenvalues, from non-Euclidean distances, give 0).
    """
    d = np.asarray(distances, dtype=np.float64)
    n = d.shape[0]
    if d.shape != (n, n):
        raise ValueError(f"distances must be square, got {d.shape}")
    if n <= dim:
        return np.zeros((n, dim))
    b = -0.5 * d**2
    b -= b.mean(axis=0, keepdims=True)
    b -= b.mean(axis=1, keepdims=True)
    if n <= _DENSE_EIGH_MAX:
        vals, vecs = np.linalg.eigh(b)
        vals, vecs = vals[::-1][:dim], vecs[:, ::-1][:, :dim]
    else:
        from scipy.sparse.linalg import eigsh

        vals, vecs = eigsh(b, k=dim, which="LA")
        order = np.argsort(vals)[::-1]
        vals, vecs = vals[order], vecs[:, order]
    # Fix each axis' sign (largest |component| positive) so plots are reproducible.
    signs = np.sign(vecs[np.argmax(np.abs(vecs), axis=0), np.arange(dim)])
    return vecs * signs * np.sqrt(np.clip(vals, 0.0, None))


def plot_embedding(
    result: SurveyClustering, path: str | Path, *, kept: tuple[int, ...] | None = None
) -> Path:
    """Scatter the MDS embedding coloured by cluster (noise grey), medoids as stars labelled
    with their cluster number (underlined by a ring when in ``kept``); writes PNG/PDF/SVG."""
    # A bare Figure (no pyplot) renders with Agg and leaves the caller's backend alone.
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    xy = classical_mds(result.distances)
    fig = Figure(figsize=(6.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    noise = result.labels == NOISE
    ax.scatter(*xy[noise].T, s=8, c="0.75", label=f"noise ({noise.sum()})")
    cmap = colormaps["tab10" if result.n_clusters <= 10 else "tab20"]
    for i, (k, size) in enumerate(
        zip(result.centroids.cluster_ids, result.centroids.sizes, strict=True)
    ):
        colour = cmap(i % cmap.N)
        members = result.labels == k
        ax.scatter(*xy[members].T, s=12, color=colour, label=f"cluster {k} ({size})")
        m = xy[result.medoids[i]]
        ax.scatter(*m, s=160, marker="*", color=colour, edgecolors="k", linewidths=0.8)
        if kept is not None and k in kept:
            ax.scatter(*m, s=420, facecolors="none", edgecolors="k", linewidths=1.0)
        ax.annotate(str(k), m, xytext=(5, 5), textcoords="offset points", fontsize=9)
    title = "Gower distances, classical MDS; stars = medoids"
    if kept is not None:
        title += ", rings = kept"
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("MDS axis 1 [-]")
    ax.set_ylabel("MDS axis 2 [-]")
    ax.legend(fontsize=7, loc="best", markerscale=1.0)
    path = Path(path)
    fig.savefig(path, dpi=130)
    return path
