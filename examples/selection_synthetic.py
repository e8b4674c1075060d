"""Select representative consignments from a synthetic survey (paper section 3, step 1).

Run: ``python examples/selection_synthetic.py [OUT_DIR]`` (default ``out/selection_example``).

1. scatter a survey of 203 consignments around the six cluster centroids of the paper's Table 1;
2. cluster it with HDBSCAN on Gower distances and print the centroid table (Table 1 layout);
3. keep four clusters by dropping the two most similar to the rest (the paper dropped 2 and 5);
4. write each kept centroid as a consignment TOML for the consignment builders.

The same run from the command line: ``flexparcel select --synthetic --keep 4 --out OUT_DIR``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from flexparcel.selection import cluster_survey, make_synthetic_survey, select_diverse
from flexparcel.selection.export import (
    centroid_table_markdown,
    consignment_from_centroid,
    read_consignment_toml,
    write_consignment_toml,
)


def main(out: Path) -> None:
    survey, _truth = make_synthetic_survey(random_state=0)
    result = cluster_survey(survey, min_cluster_size=10)
    table = result.centroids
    print(centroid_table_markdown(table))

    selection = select_diverse(
        result.centroid_distances(), keep=4, cluster_ids=table.cluster_ids, sizes=table.sizes
    )
    print(f"kept {selection.kept}, dropped {selection.dropped} (most redundant first)")

    out.mkdir(parents=True, exist_ok=True)
    for k in selection.kept:
        spec = consignment_from_centroid(table, k)
        path = write_consignment_toml(spec, out / f"{spec.id}.toml")
        assert read_consignment_toml(path) == spec  # the file the builders will read
        print(
            f"{path}: {spec.packaging_material}, {spec.length_mm:g} x {spec.width_mm:g} x "
            f"{spec.height_mm:g} mm, {spec.mass_g:g} g, {spec.content_kind} content"
        )


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/selection_example"))
