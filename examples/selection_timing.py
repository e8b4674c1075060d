"""Time the Gower distance matrix for a 10,000-row survey (issue 7 acceptance figure).

Run: ``python examples/selection_timing.py [ROWS] [--cluster]``. Prints seconds for the
(ROWS x ROWS) float32 matrix; with ``--cluster`` also times HDBSCAN on it (needs about
3x the matrix in memory: our float32 matrix plus HDBSCAN's float64 working copy).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from flexparcel.selection import gower_distances, hdbscan_labels, make_synthetic_survey


def main(argv: list[str]) -> None:
    rows = int(argv[0]) if argv and not argv[0].startswith("-") else 10_000
    # The six Table 1 clusters scaled up (203 rows at scale 1), 10 % noise rows, then cut to size.
    scale = 0.9 * rows / 203 + 1
    survey, _ = make_synthetic_survey(scale=scale, n_noise=rows // 10, random_state=0)
    survey = survey.subset(np.arange(rows))
    p, q = survey.numeric.shape[1], survey.categorical.shape[1]
    print(f"survey: {rows} rows, {p} numeric/ordinal + {q} categorical/boolean columns")

    gower_distances(survey.subset(np.arange(min(rows, 500))))  # warm-up (page faults, caches)
    t0 = time.perf_counter()
    d = gower_distances(survey)
    t1 = time.perf_counter()
    print(f"Gower {rows} x {rows} ({d.dtype}, {d.nbytes / 2**20:.0f} MiB): {t1 - t0:.2f} s")
    if "--cluster" in argv:
        t0 = time.perf_counter()
        labels, _ = hdbscan_labels(d, min_cluster_size=max(10, rows // 200))
        t1 = time.perf_counter()
        k = labels.max()
        print(f"HDBSCAN on it: {t1 - t0:.2f} s, {k} clusters, {np.mean(labels < 0):.0%} noise")


if __name__ == "__main__":
    main(sys.argv[1:])
