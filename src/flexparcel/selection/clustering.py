"""HDBSCAN clustering of a survey on Gower distances, centroid table, medoids, diverse selection.

The paper (section 3, "Selection of a specific consignment", after Stadlthanner et al.) clusters
657 surveyed consignments with HDBSCAN on Gower distances, reports the cluster centroids
(Table 1: size, then median of numeric/ordinal and mode of categorical/boolean columns) and keeps
four of the six clusters, discarding the two "most similar to the remaining clusters based on
Gower's distance". :func:`select_diverse` makes that rule explicit: repeatedly drop the cluster
whose mean Gower distance to the other remaining centroids is smallest. On the six published
centroids (ranges taken from those centroids, the only published data) it drops clusters 2 and 5,
as the paper did.

Cluster numbering follows the paper: clusters are numbered 1..K by decreasing size (ties: the one
whose first member comes first), noise is -1.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from flexparcel.selection.gower import feature_ranges, gower_distances
from flexparcel.selection.survey import Survey, SurveySchema, survey_from_records

__all__ = [
    "NOISE",
    "CentroidTable",
    "SurveyClustering",
    "DiverseSelection",
    "hdbscan_labels",
    "centroid_table",
    "cluster_survey",
    "select_diverse",
]

NOISE = -1


@dataclass(frozen=True)
class CentroidTable:
    """Cluster centroids in the form of the paper's Table 1.

    Attributes
    ----------
    schema : the survey columns (units as declared there).
    cluster_ids : cluster numbers 1..K.
    sizes : members per cluster.
    values : per cluster, column -> centroid value: median for numeric columns (column unit),
        lower median level for ordinal ones (a real level), mode for categorical/boolean ones
        (ties: first level in level order); ``None`` if every member misses the column.
    medoid_ids : per cluster, the id of its medoid (the member with the least summed Gower distance
        to the other members: a real consignment, unlike the centroid).
    n_rows, n_noise : survey rows, of which noise.
    """

    schema: SurveySchema
    cluster_ids: tuple[int, ...]
    sizes: tuple[int, ...]
    values: tuple[dict[str, object], ...]
    medoid_ids: tuple[str, ...]
    n_rows: int
    n_noise: int

    def row(self, cluster: int) -> dict[str, object]:
        """The centroid values of cluster number ``cluster``."""
        if cluster not in self.cluster_ids:
            raise KeyError(f"no cluster {cluster} (clusters: {list(self.cluster_ids)})")
        return dict(self.values[self.cluster_ids.index(cluster)])

    def as_survey(self) -> Survey:
        """The centroids encoded as a survey (ids ``"cluster<k>"``), for Gower distances."""
        records = [
            {"__id": f"cluster{k}", **v} for k, v in zip(self.cluster_ids, self.values, strict=True)
        ]
        schema = SurveySchema(self.schema.columns, id_column="__id")
        return survey_from_records(records, schema, source="centroid table")


@dataclass(frozen=True, eq=False)
class SurveyClustering:
    """Result of :func:`cluster_survey`.

    Attributes
    ----------
    survey : the clustered survey.
    distances : (n, n) float32 Gower distances.
    labels : (n,) int, cluster number 1..K or :data:`NOISE` (-1).
    probabilities : (n,) HDBSCAN membership strength in [0, 1] (0 for noise).
    medoids : (K,) row index of each cluster's medoid.
    centroids : the centroid table.
    weights, ranges : Gower weights and ranges used (column -> value), reused for centroids.
    min_cluster_size, min_samples : HDBSCAN parameters used.
    """

    survey: Survey
    distances: np.ndarray
    labels: np.ndarray
    probabilities: np.ndarray
    medoids: np.ndarray
    centroids: CentroidTable
    weights: dict[str, float]
    ranges: dict[str, float]
    min_cluster_size: int
    min_samples: int | None

    @property
    def n_clusters(self) -> int:
        """Number of clusters K."""
        return len(self.centroids.cluster_ids)

    @property
    def noise(self) -> np.ndarray:
        """Row indices labelled noise."""
        return np.flatnonzero(self.labels == NOISE)

    def centroid_distances(self) -> np.ndarray:
        """(K, K) float64 Gower distances between centroids, with the survey's weights and ranges
        (so a centroid pair is compared on the same scale as the consignments)."""
        c = self.centroids.as_survey()
        return gower_distances(c, weights=self.weights, ranges=self.ranges, dtype=np.float64)


@dataclass(frozen=True)
class DiverseSelection:
    """Result of :func:`select_diverse`.

    kept : cluster numbers kept, ascending. dropped : cluster numbers in the order dropped.
    mean_distance_at_drop : for each dropped cluster, its mean Gower distance to the other
    clusters remaining at that step (the redundancy score that made it go).
    """

    kept: tuple[int, ...]
    dropped: tuple[int, ...]
    mean_distance_at_drop: tuple[float, ...]


def hdbscan_labels(
    distances: np.ndarray, *, min_cluster_size: int = 10, min_samples: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """HDBSCAN (scikit-learn, ``metric="precomputed"``) on a distance matrix.

    Returns ``(labels, probabilities)``, labels renumbered 1..K by decreasing cluster size,
    -1 = noise. ``min_cluster_size`` (>= 2) is the smallest group called a cluster;
    ``min_samples`` (>= 1, default = ``min_cluster_size``) sets how conservative the density
    estimate is (larger: more points declared noise).
    """
    from sklearn.cluster import HDBSCAN

    d = np.asarray(distances)
    n = d.shape[0]
    if d.ndim != 2 or d.shape != (n, n):
        raise ValueError(f"distances must be a square matrix, got shape {d.shape}")
    if n < 2:
        raise ValueError("clustering needs at least 2 survey rows")
    if isinstance(min_cluster_size, bool) or not isinstance(min_cluster_size, int | np.integer):
        raise ValueError(f"min_cluster_size must be an integer, got {min_cluster_size!r}")
    if not 2 <= min_cluster_size <= n:
        raise ValueError(f"min_cluster_size = {min_cluster_size} must be in [2, {n}] (rows)")
    if min_samples is not None and not 1 <= int(min_samples) <= n:
        raise ValueError(f"min_samples = {min_samples} must be in [1, {n}] (rows)")
    bad = np.argwhere(np.isnan(d))
    if bad.size:
        i, j = bad[0]
        raise ValueError(
            f"rows {i} and {j} share no observed feature, their Gower distance is undefined; "
            "fill in or drop such rows"
        )
    # HDBSCAN rewrites a float64 input in place (mutual reachability); give it its own copy so
    # the caller's matrix survives.
    work = np.array(d, dtype=np.float64, copy=True)
    model = HDBSCAN(
        metric="precomputed",
        min_cluster_size=int(min_cluster_size),
        min_samples=None if min_samples is None else int(min_samples),
        copy=False,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        raw = model.fit_predict(work)
    probabilities = np.asarray(model.probabilities_, dtype=np.float64)
    return _renumber_by_size(raw), probabilities


def _renumber_by_size(raw: np.ndarray) -> np.ndarray:
    labels = np.full(raw.shape, NOISE, dtype=np.int64)
    found = [c for c in np.unique(raw) if c >= 0]
    # Sort by size (descending), then by first member, so numbering is deterministic.
    order = sorted(found, key=lambda c: (-np.count_nonzero(raw == c), np.argmax(raw == c)))
    for k, c in enumerate(order, start=1):
        labels[raw == c] = k
    return labels


def centroid_table(
    survey: Survey, labels: np.ndarray, distances: np.ndarray | None = None
) -> tuple[CentroidTable, np.ndarray]:
    """Centroids (median / mode per column) and medoids of the labelled clusters.

    ``labels``: (n,) cluster numbers, :data:`NOISE` excluded. ``distances``: the (n, n) Gower
    matrix for the medoids (computed when ``None``). Returns the table and the (K,) medoid rows.
    """
    labels = np.asarray(labels)
    if labels.shape != (len(survey),):
        raise ValueError(f"labels must have shape ({len(survey)},), got {labels.shape}")
    if distances is None:
        distances = gower_distances(survey)
    schema = survey.schema
    ids = sorted(int(c) for c in np.unique(labels) if c != NOISE)
    values, sizes, medoids = [], [], []
    for k in ids:
        members = np.flatnonzero(labels == k)
        row: dict[str, object] = {}
        for j, spec in enumerate(schema.numeric_columns):
            x = survey.numeric[members, j]
            x = np.sort(x[~np.isnan(x)])
            if x.size == 0:
                row[spec.name] = None
            elif spec.kind == "numeric":
                row[spec.name] = float(np.median(x))
            else:
                # Lower median of the ranks: always an existing level, as in Table 1.
                row[spec.name] = spec.levels[int(x[(x.size - 1) // 2])]
        for j, spec in enumerate(schema.categorical_columns):
            codes = survey.categorical[members, j]
            codes = codes[codes >= 0]
            levels = survey.categorical_levels[j]
            if codes.size == 0:
                row[spec.name] = None
            else:
                counts = np.bincount(codes, minlength=len(levels))
                row[spec.name] = levels[int(np.argmax(counts))]  # argmax: first of ties
        values.append({name: row[name] for name in schema.names})
        sizes.append(int(members.size))
        sub = np.asarray(distances[np.ix_(members, members)], dtype=np.float64)
        medoids.append(int(members[np.argmin(sub.sum(axis=1))]))
    table = CentroidTable(
        schema=schema,
        cluster_ids=tuple(ids),
        sizes=tuple(sizes),
        values=tuple(values),
        medoid_ids=tuple(survey.ids[m] for m in medoids),
        n_rows=len(survey),
        n_noise=int(np.count_nonzero(labels == NOISE)),
    )
    return table, np.asarray(medoids, dtype=np.intp)


def cluster_survey(
    survey: Survey,
    *,
    min_cluster_size: int = 10,
    min_samples: int | None = None,
    weights: Mapping[str, float] | None = None,
    ranges: Mapping[str, float] | str = "data",
) -> SurveyClustering:
    """Gower distances + HDBSCAN + centroid table + medoids, in one call.

    ``weights`` / ``ranges`` as in :func:`~flexparcel.selection.gower.gower_distances`;
    ``min_cluster_size`` / ``min_samples`` as in :func:`hdbscan_labels`.
    """
    w = {c.name: c.weight for c in survey.schema.columns}
    w.update({k: float(v) for k, v in (weights or {}).items()})
    r = (
        feature_ranges(survey, source=ranges)
        if isinstance(ranges, str)
        else {k: float(v) for k, v in ranges.items()}
    )
    d = gower_distances(survey, weights=w, ranges=r)
    labels, prob = hdbscan_labels(d, min_cluster_size=min_cluster_size, min_samples=min_samples)
    table, medoids = centroid_table(survey, labels, d)
    return SurveyClustering(
        survey=survey,
        distances=d,
        labels=labels,
        probabilities=prob,
        medoids=medoids,
        centroids=table,
        weights=w,
        ranges=r,
        min_cluster_size=min_cluster_size,
        min_samples=min_samples,
    )


def select_diverse(
    distances: np.ndarray,
    keep: int,
    *,
    cluster_ids: Sequence[int] | None = None,
    sizes: Sequence[int] | None = None,
) -> DiverseSelection:
    """Keep ``keep`` clusters by repeatedly dropping the most redundant one.

    Each step drops the cluster with the smallest mean Gower distance to the other clusters still
    kept (the one "most similar to the remaining clusters"); ties go to the smaller cluster
    (``sizes``), then to the higher number. Greedy, so dropping one cluster re-scores the rest.

    Parameters
    ----------
    distances : (K, K) Gower distances between centroids (e.g.
        :meth:`SurveyClustering.centroid_distances`).
    keep : clusters to keep, 1 <= keep <= K.
    cluster_ids : numbers of the K clusters (default 1..K). sizes : members per cluster.
    """
    d = np.asarray(distances, dtype=np.float64)
    k_all = d.shape[0]
    if d.shape != (k_all, k_all) or k_all == 0:
        raise ValueError(f"distances must be a non-empty square matrix, got shape {d.shape}")
    if not np.all(np.isfinite(d)):
        raise ValueError("centroid distances contain NaN/inf (a centroid with no values?)")
    ids = list(range(1, k_all + 1)) if cluster_ids is None else [int(c) for c in cluster_ids]
    size = [0] * k_all if sizes is None else [int(s) for s in sizes]
    if len(ids) != k_all or len(size) != k_all:
        raise ValueError("cluster_ids and sizes must have one entry per cluster")
    if not 1 <= keep <= k_all:
        raise ValueError(f"keep = {keep} must be in [1, {k_all}] (clusters found)")
    remaining = list(range(k_all))
    dropped, scores = [], []
    while len(remaining) > keep:
        sub = d[np.ix_(remaining, remaining)]
        mean = sub.sum(axis=1) / max(len(remaining) - 1, 1)
        pos = min(
            range(len(remaining)),
            key=lambda a: (mean[a], size[remaining[a]], -ids[remaining[a]]),
        )
        scores.append(float(mean[pos]))
        dropped.append(ids[remaining.pop(pos)])
    return DiverseSelection(
        kept=tuple(sorted(ids[i] for i in remaining)),
        dropped=tuple(dropped),
        mean_distance_at_drop=tuple(scores),
    )
