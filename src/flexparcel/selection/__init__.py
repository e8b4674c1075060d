"""Selection of representative consignments from a survey (paper section 3, step 1).

Gower distances (:mod:`~flexparcel.selection.gower`) on a validated survey
(:mod:`~flexparcel.selection.survey`), HDBSCAN clusters with a Table-1-style centroid table and
a diverse subset (:mod:`~flexparcel.selection.clustering`), synthetic surveys seeded from the
paper (:mod:`~flexparcel.selection.synthetic`), and output files including the consignment TOML
read by the consignment builders (:mod:`~flexparcel.selection.export`). scikit-learn and
matplotlib are imported only by the functions that need them.
"""

from flexparcel.selection.clustering import (
    NOISE,
    CentroidTable,
    DiverseSelection,
    SurveyClustering,
    centroid_table,
    cluster_survey,
    hdbscan_labels,
    select_diverse,
)
from flexparcel.selection.gower import feature_ranges, gower_distances, gower_from_arrays
from flexparcel.selection.survey import (
    ColumnSpec,
    Survey,
    SurveyError,
    SurveySchema,
    describe_schema,
    infer_schema,
    read_schema,
    read_survey,
    survey_from_records,
    write_schema,
    write_survey_csv,
)
from flexparcel.selection.synthetic import (
    PAPER_TABLE1,
    make_synthetic_survey,
    paper_centroid_survey,
    synthetic_schema,
)

__all__ = [
    "NOISE",
    "CentroidTable",
    "ColumnSpec",
    "DiverseSelection",
    "PAPER_TABLE1",
    "Survey",
    "SurveyClustering",
    "SurveyError",
    "SurveySchema",
    "centroid_table",
    "cluster_survey",
    "describe_schema",
    "feature_ranges",
    "gower_distances",
    "gower_from_arrays",
    "hdbscan_labels",
    "infer_schema",
    "make_synthetic_survey",
    "paper_centroid_survey",
    "read_schema",
    "read_survey",
    "select_diverse",
    "survey_from_records",
    "synthetic_schema",
    "write_schema",
    "write_survey_csv",
]
