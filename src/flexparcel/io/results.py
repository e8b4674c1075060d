"""Results as a single ``.npz`` file: plain arrays only, read back with ``allow_pickle=False``.

Layout: ``time`` (k,), ``positions`` (k, n, 3), ``rotation_vectors`` (k, n, 3),
``velocities`` (k, n, 6), ``energy_<name>`` (k,), ``cells_<type>`` connectivity, and
``meta_json`` (a JSON string: format version, statistics). Written atomically (temporary file
then rename), so an interrupted write never leaves a truncated results file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from flexparcel.io.atomic import write_atomic

__all__ = ["save_result", "load_result", "RESULTS_FORMAT_VERSION"]

RESULTS_FORMAT_VERSION = 1


def save_result(path: str | Path, result, model=None, extra_meta: dict | None = None) -> Path:
    """Write a :class:`flexparcel.SimulationResult` to ``path`` (``.npz``)."""
    arrays = {
        "time": result.time,
        "positions": result.positions,
        "rotation_vectors": result.rotation_vectors,
        "velocities": result.velocities,
    }
    for k, v in result.energies.items():
        arrays[f"energy_{k}"] = np.asarray(v)
    if model is not None:
        for ctype, conn in model.cells:
            arrays[f"cells_{ctype}"] = conn
        arrays["reference_positions"] = model.positions0
    for k, v in arrays.items():
        if np.issubdtype(np.asarray(v).dtype, np.floating) and not np.all(np.isfinite(v)):
            raise ValueError(f"save_result: '{k}' contains non-finite values; refusing to write")
    meta = {
        "format": "flexparcel-results",
        "version": RESULTS_FORMAT_VERSION,
        "stats": result.stats,
        **(extra_meta or {}),
    }
    arrays["meta_json"] = np.array(json.dumps(meta, default=float))
    path = Path(path)
    write_atomic(path, lambda f: np.savez_compressed(f, **arrays))
    return path


def load_result(path: str | Path) -> dict:
    """Read a results file into a dict of arrays plus ``meta`` (dict)."""
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    meta = json.loads(str(data.pop("meta_json")))
    if meta.get("format") != "flexparcel-results":
        raise ValueError(f"{path}: not a flexparcel results file")
    if meta.get("version") != RESULTS_FORMAT_VERSION:
        raise ValueError(
            f"{path}: results format version {meta.get('version')!r}; this flexparcel reads "
            f"version {RESULTS_FORMAT_VERSION}"
        )
    data["meta"] = meta
    return data
