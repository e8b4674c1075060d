"""``flexparcel select``: cluster a consignment survey and pick representative consignments.

Reads a survey (CSV, or Parquet with pyarrow), computes Gower distances, clusters them with
HDBSCAN, keeps ``--keep`` diverse clusters and writes into ``--out``:

``schema.toml``            the schema used (inferred ones can be edited and passed back)
``labels.csv``             id, cluster (-1 = noise), membership probability per row
``centroids.csv`` / ``.md``  the centroid table (paper Table 1 layout) with medoids
``centroid_distances.csv`` Gower distances between centroids
``selection.csv``          kept / dropped clusters, drop order and redundancy score
``consignments/C<k>.toml`` a consignment file per kept cluster (when the columns allow)
``embedding.png``          classical-MDS map of the Gower distances coloured by cluster
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``select`` sub-command to the ``flexparcel`` parser."""
    p = subparsers.add_parser(
        "select",
        help="cluster a consignment survey (Gower + HDBSCAN) and pick representatives",
        description=(
            "Cluster a survey of consignments with HDBSCAN on Gower distances, write the "
            "centroid table, a diverse selection of clusters and consignment TOML files."
        ),
    )
    p.add_argument("survey", nargs="?", type=Path, help="survey file (.csv, .tsv, .parquet)")
    p.add_argument("--schema", type=Path, help="schema TOML (default: inferred and printed)")
    p.add_argument(
        "--synthetic",
        action="store_true",
        help="use a synthetic survey seeded from the paper's Table 1 instead of a file",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of --synthetic (default 0)")
    p.add_argument(
        "--min-cluster-size", type=int, default=10, help="HDBSCAN min_cluster_size (default 10)"
    )
    p.add_argument("--min-samples", type=int, help="HDBSCAN min_samples (default: = size)")
    p.add_argument("--keep", type=int, help="clusters to keep (default: all)")
    p.add_argument(
        "--weight",
        action="append",
        default=[],
        metavar="COLUMN=W",
        help="Gower weight of a column (repeatable)",
    )
    p.add_argument(
        "--exclude",
        action="append",
        default=[],
        metavar="COLUMN",
        help="leave a column out of an inferred schema (repeatable)",
    )
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--no-plot", action="store_true", help="skip embedding.png")
    p.set_defaults(func=run, out_is_dir=True)


def _parse_weights(items: list[str]) -> dict[str, float]:
    weights = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            weights[name.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep or not name.strip():
            raise ValueError(f"--weight {item!r}: expected COLUMN=NUMBER, e.g. mass_g=2")
    return weights


def run(args: argparse.Namespace) -> int:
    """Execute ``flexparcel select``; returns the exit code (1 when no cluster is found)."""
    from flexparcel.io.atomic import atomic_path, write_atomic
    from flexparcel.selection import (
        cluster_survey,
        describe_schema,
        make_synthetic_survey,
        read_survey,
        select_diverse,
        write_schema,
        write_survey_csv,
    )
    from flexparcel.selection.export import (
        centroid_table_markdown,
        consignment_from_centroid,
        write_centroid_csv,
        write_consignment_toml,
        write_csv,
        write_labels_csv,
        write_selection_csv,
    )

    if (args.survey is None) == (not args.synthetic):
        raise ValueError("give either a survey file or --synthetic (not both)")
    if args.keep is not None and args.keep < 1:
        raise ValueError(f"--keep {args.keep}: keep at least 1 cluster")
    weights = _parse_weights(args.weight)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)

    if args.synthetic:
        survey, _ = make_synthetic_survey(random_state=args.seed)
        with atomic_path(out / "survey.csv") as tmp:
            write_survey_csv(survey, tmp)
        print(f"synthetic survey ({len(survey)} rows, seed {args.seed}) -> {out / 'survey.csv'}")
    else:
        survey = read_survey(args.survey, args.schema, exclude=args.exclude)
        print(f"read {len(survey)} rows from {args.survey}")
        if args.schema is None:
            print("inferred schema (write your own TOML with --schema to change it):")
            print(describe_schema(survey.schema, survey))
    with atomic_path(out / "schema.toml") as tmp:
        write_schema(survey.schema, tmp)

    result = cluster_survey(
        survey,
        min_cluster_size=args.min_cluster_size,
        min_samples=args.min_samples,
        weights=weights,
    )
    write_labels_csv(result, out / "labels.csv")
    table = result.centroids
    print(
        f"HDBSCAN (min_cluster_size={args.min_cluster_size}, min_samples={args.min_samples}): "
        f"{result.n_clusters} clusters, {len(result.noise)} of {len(survey)} rows noise"
    )
    if result.n_clusters == 0:
        print(
            "no cluster found; try a smaller --min-cluster-size (labels.csv written)",
            file=sys.stderr,
        )
        return 1

    keep = result.n_clusters if args.keep is None else args.keep
    if keep > result.n_clusters:
        print(
            f"warning: --keep {keep} but only {result.n_clusters} clusters found; keeping all",
            file=sys.stderr,
        )
        keep = result.n_clusters
    cd = result.centroid_distances()
    selection = select_diverse(cd, keep, cluster_ids=table.cluster_ids, sizes=table.sizes)

    markdown = centroid_table_markdown(table)
    write_atomic(out / "centroids.md", markdown)
    write_centroid_csv(table, out / "centroids.csv")
    write_selection_csv(table, selection, out / "selection.csv")
    write_csv(
        out / "centroid_distances.csv",
        ["cluster", *table.cluster_ids],
        ([k, *(f"{v:.6f}" for v in row)] for k, row in zip(table.cluster_ids, cd, strict=True)),
    )

    print()
    print(markdown)
    print(f"kept clusters: {', '.join(map(str, selection.kept))}")
    if selection.dropped:
        print(f"dropped (most similar to the rest first): {', '.join(map(str, selection.dropped))}")

    cons_dir = out / "consignments"
    written = []
    for k in selection.kept:
        try:
            spec = consignment_from_centroid(table, k)
        except (ValueError, KeyError) as exc:
            print(f"consignment file for cluster {k} not written: {exc}", file=sys.stderr)
            continue
        cons_dir.mkdir(exist_ok=True)
        target = cons_dir / f"{spec.id}.toml"
        with atomic_path(target) as tmp:
            write_consignment_toml(spec, tmp)
        written.append(target)
    if written:
        print(f"consignment files: {', '.join(str(p) for p in written)}")

    if not args.no_plot:
        from flexparcel.selection.plot import plot_embedding

        with atomic_path(out / "embedding.png") as tmp:
            plot_embedding(result, tmp, kept=selection.kept)
    print(f"outputs in {out}")
    return 0
