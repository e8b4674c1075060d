"""Synthetic consignment surveys seeded from the paper's Table 1 centroids.

The real survey (657 consignments from an Austrian distribution centre, Stadlthanner et al.) is
not public; only the six HDBSCAN centroids are (Table 1 of the paper, copied below; the tests
check the copy against ``tests/data/reference/cluster-centroids.csv``).
:func:`make_synthetic_survey` scatters consignments around given centroids, so tests and
examples can check that clustering recovers known groups.

Scatter model, per cluster member: numeric columns log-normal around the centroid (relative
spread :data:`DEFAULT_SPREAD`), rounded to 0.5 cm (length, width), 0.1 cm (height) and 5 g, and
clipped to the schema bounds; each ordinal class moves to a neighbouring level with probability
``ordinal_flip`` (classes judged by eye are noisy); categorical and boolean columns keep the
centroid value. Optional noise rows are drawn broadly over the schema.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from flexparcel.selection.survey import ColumnSpec, Survey, SurveySchema, survey_from_records

__all__ = [
    "PAPER_TABLE1",
    "PACKAGING_LEVELS",
    "DEFAULT_SPREAD",
    "synthetic_schema",
    "paper_centroid_survey",
    "make_synthetic_survey",
]

PACKAGING_LEVELS = ("kraft paper w/ bubble wrap", "polybag", "kraft paper", "bubble wrap")
# Table 1 only shows "flat"; the other shape labels are placeholders for survey forms.
SHAPE_LEVELS = ("flat", "cuboid", "irregular")

# Table 1 of the paper (cluster, size, then the centroid). Units: cm and g, as printed.
_TABLE1_COLUMNS = (
    "cluster", "cluster_size", "packaging", "shape", "content_movable", "content_multipart",
    "flexibility", "filling_level", "length_cm", "width_cm", "height_cm", "mass_g",
)  # fmt: skip
_KPBW = "kraft paper w/ bubble wrap"
_TABLE1_ROWS = (
    (1, 75, _KPBW, "flat", True, False, 1, 3, 27.0, 19.0, 2.0, 140.0),
    (2, 60, _KPBW, "flat", False, False, 1, 4, 23.0, 16.0, 2.0, 80.0),
    (3, 24, "polybag", "flat", False, False, 2, 4, 29.0, 22.0, 2.0, 180.0),
    (4, 17, "kraft paper", "flat", False, False, 1, 4, 33.0, 25.0, 3.0, 380.0),
    (5, 16, "kraft paper", "flat", True, False, 1, 3, 32.0, 20.0, 2.0, 140.0),
    (6, 11, "bubble wrap", "flat", False, False, 1, 4, 16.0, 13.0, 2.0, 80.0),
)
PAPER_TABLE1: tuple[dict[str, object], ...] = tuple(
    dict(zip(_TABLE1_COLUMNS, row, strict=True)) for row in _TABLE1_ROWS
)

# Relative (log-normal sigma) spread of the numeric columns around a centroid.
DEFAULT_SPREAD = {"length_cm": 0.06, "width_cm": 0.06, "height_cm": 0.15, "mass_g": 0.12}
_RESOLUTION = {"length_cm": 0.5, "width_cm": 0.5, "height_cm": 0.1, "mass_g": 5.0}


def synthetic_schema() -> SurveySchema:
    """The survey columns of the paper (names as in ``cluster-centroids.csv``, id column ``id``).

    Bounds: length/width 1-150 cm, height 0.5-80 cm, mass 1-31500 g (the 31.5 kg parcel limit);
    flexibility 1..3 (overhang <5 deg, 5-45 deg, >45 deg), filling level 1..4 (<25 %, 25-50 %,
    50-75 %, >75 %).
    """
    return SurveySchema(
        columns=(
            ColumnSpec("packaging", "categorical", levels=PACKAGING_LEVELS),
            ColumnSpec("shape", "categorical", levels=SHAPE_LEVELS),
            ColumnSpec("content_movable", "boolean"),
            ColumnSpec("content_multipart", "boolean"),
            ColumnSpec("flexibility", "ordinal", levels=(1, 2, 3)),
            ColumnSpec("filling_level", "ordinal", levels=(1, 2, 3, 4)),
            ColumnSpec("length_cm", "numeric", minimum=1.0, maximum=150.0, unit="cm"),
            ColumnSpec("width_cm", "numeric", minimum=1.0, maximum=150.0, unit="cm"),
            ColumnSpec("height_cm", "numeric", minimum=0.5, maximum=80.0, unit="cm"),
            ColumnSpec("mass_g", "numeric", minimum=1.0, maximum=31500.0, unit="g"),
        ),
        id_column="id",
    )


def paper_centroid_survey() -> Survey:
    """The six Table 1 centroids as a survey (ids ``"cluster1"`` .. ``"cluster6"``)."""
    schema = synthetic_schema()
    records = [
        {"id": f"cluster{row['cluster']}", **{n: row[n] for n in schema.names}}
        for row in PAPER_TABLE1
    ]
    return survey_from_records(records, schema, source="paper Table 1")


def make_synthetic_survey(
    centroids: Sequence[Mapping[str, object]] | None = None,
    sizes: Sequence[int] | None = None,
    *,
    scale: float = 1.0,
    n_noise: int = 0,
    spread: Mapping[str, float] | None = None,
    ordinal_flip: float = 0.05,
    random_state: int | np.random.Generator | None = None,
) -> tuple[Survey, np.ndarray]:
    """A shuffled synthetic survey and its generating labels.

    Parameters
    ----------
    centroids : cluster centres with the :func:`synthetic_schema` columns (default: the six of
        :data:`PAPER_TABLE1`). Build redundant clusters by passing extra centres.
    sizes : members per cluster (default: each centroid's ``cluster_size``, else 30).
    scale : multiplies the sizes (at least 2 members per cluster remain).
    n_noise : extra rows drawn broadly over the schema, labelled -1.
    spread : log-normal sigma per numeric column (default :data:`DEFAULT_SPREAD`).
    ordinal_flip : probability, per member and ordinal column, of moving one level up or down.
    random_state : seed or generator.

    Returns
    -------
    (survey, labels) : labels (n,) int, 1..K in the order of ``centroids``, -1 for noise rows.
    """
    rng = np.random.default_rng(random_state)
    schema = synthetic_schema()
    centres = list(PAPER_TABLE1 if centroids is None else centroids)
    if sizes is None:
        sizes = [int(c.get("cluster_size", 30)) for c in centres]
    if len(sizes) != len(centres):
        raise ValueError(f"{len(sizes)} sizes given for {len(centres)} centroids")
    if not 0.0 <= ordinal_flip <= 1.0:
        raise ValueError(f"ordinal_flip = {ordinal_flip} must be in [0, 1]")
    if scale <= 0 or n_noise < 0:
        raise ValueError("scale must be > 0 and n_noise >= 0")
    sigma = dict(DEFAULT_SPREAD if spread is None else spread)

    records: list[dict[str, object]] = []
    labels: list[int] = []
    for k, (centre, size) in enumerate(zip(centres, sizes, strict=True), start=1):
        missing = [n for n in schema.names if n not in centre]
        if missing:
            raise ValueError(f"centroid {k} lacks column(s) {', '.join(missing)}")
        for _ in range(max(2, round(size * scale))):
            rec: dict[str, object] = {}
            for spec in schema.columns:
                v = centre[spec.name]
                if spec.kind == "numeric":
                    x = float(v) * np.exp(sigma.get(spec.name, 0.0) * rng.standard_normal())
                    res = _RESOLUTION.get(spec.name, 0.0)
                    x = round(x / res) * res if res else x
                    rec[spec.name] = float(np.clip(x, spec.minimum, spec.maximum))
                elif spec.kind == "ordinal":
                    rank = list(spec.levels).index(v)
                    if rng.random() < ordinal_flip:
                        rank = int(np.clip(rank + rng.choice((-1, 1)), 0, len(spec.levels) - 1))
                    rec[spec.name] = spec.levels[rank]
                else:
                    rec[spec.name] = v
            records.append(rec)
            labels.append(k)
    for _ in range(n_noise):
        length = rng.uniform(10.0, 60.0)
        records.append(
            {
                "packaging": rng.choice(PACKAGING_LEVELS),
                "shape": rng.choice(SHAPE_LEVELS),
                "content_movable": bool(rng.random() < 0.5),
                "content_multipart": bool(rng.random() < 0.2),
                "flexibility": int(rng.integers(1, 4)),
                "filling_level": int(rng.integers(1, 5)),
                "length_cm": round(length * 2) / 2,
                "width_cm": round(length * rng.uniform(0.4, 0.9) * 2) / 2,
                "height_cm": round(rng.uniform(0.5, 10.0) * 2) / 2,
                "mass_g": round(np.exp(rng.uniform(np.log(30.0), np.log(3000.0))) / 5) * 5.0,
            }
        )
        labels.append(-1)

    order = rng.permutation(len(records))
    rows = []
    for new_index, old in enumerate(order):
        rows.append({"id": f"S{new_index + 1:05d}", **records[old]})
    survey = survey_from_records(rows, schema, source="synthetic survey")
    return survey, np.asarray(labels, dtype=np.int64)[order]
