"""Results as a single ``.npz`` file: plain arrays only, read back with ``allow_pickle=False``.

Layout: ``time`` (k,), ``positions`` (k, n, 3), ``rotation_vectors`` (k, n, 3),
``velocities`` (k, n, 6), ``energy_<name>`` (k,), ``cells_<type>`` connectivity, and
``meta_json`` (a JSON string: format version, statistics). Written atomically (temporary file
then rename), so an interrupted write never leaves a truncated results file.
"""

from __future__ import annotations

import json
import pickle
import zipfile
import zlib
from pathlib import Path

import numpy as np

from flexparcel.io.atomic import write_atomic

__all__ = ["save_result", "load_result", "read_npz", "FileFormatError", "RESULTS_FORMAT_VERSION"]

RESULTS_FORMAT_VERSION = 1


class FileFormatError(ValueError):
    """A flexparcel file (results, snapshot, checkpoint) that cannot be read: truncated,
    damaged, empty, of another format or version, or missing an entry. The message starts
    with what the file is and its path. Subclasses: ``SnapshotError``
    (:mod:`flexparcel.consignments.snapshot`), ``CheckpointError``
    (:mod:`flexparcel.io.checkpoint`). A file that does not exist raises
    ``FileNotFoundError`` instead."""


# what numpy, zipfile and zlib raise on a truncated, bit-flipped, empty or foreign .npz
_NPZ_ERRORS = (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error,
               pickle.UnpicklingError)  # fmt: skip


def read_npz(path: str | Path, what: str, error: type[Exception] = FileFormatError) -> dict:
    """Every array of the ``.npz`` file ``path`` (``allow_pickle=False``), read in full.

    ``FileNotFoundError`` for a missing file; ``error`` (default :class:`FileFormatError`),
    with a message ``"<what> <path>: ..."``, for anything numpy cannot read as an ``.npz``
    archive: an empty, truncated or damaged file, a ``.npy`` or a file of another kind."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{what} not found: {path}")
    if path.is_dir():
        raise error(f"{what} {path}: is a directory, not an .npz file")
    if path.stat().st_size == 0:
        raise error(f"{what} {path}: the file is empty (an interrupted copy or write?)")
    with path.open("rb") as fh:
        head = fh.read(8)
    if not head.startswith((b"PK\x03\x04", b"PK\x05\x06")):
        kind = "a single .npy array" if head.startswith(b"\x93NUMPY") else "a file of another kind"
        raise error(
            f"{what} {path}: not a readable .npz file (not a flexparcel {what}: {kind}, "
            f"starting with {head!r})"
        )
    try:
        # numpy reads a member only as far as its array goes, which skips the CRC check of a
        # damaged byte; testzip reads every member to its end and checks them all
        with zipfile.ZipFile(path) as archive:
            bad = archive.testzip()
        if bad is not None:
            raise zipfile.BadZipFile(f"Bad CRC-32 for file {bad!r}")
        z = np.load(path, allow_pickle=False)
        if not isinstance(z, np.lib.npyio.NpzFile):
            raise ValueError("a single .npy array, not an .npz archive")
        with z:
            return {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise
    except _NPZ_ERRORS as exc:
        reason = str(exc) or type(exc).__name__
        if isinstance(exc, EOFError | zipfile.BadZipFile | zlib.error):
            reason = f"truncated or damaged ({reason})"
        raise error(f"{what} {path}: not a readable .npz file: {reason}") from exc


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
    """Read a results file into a dict of arrays plus ``meta`` (dict).

    Raises :class:`FileFormatError` naming the file for an empty, truncated, damaged or
    foreign file, a missing entry, or another format version; ``FileNotFoundError`` for a
    missing file."""
    what = "results file"
    data = read_npz(path, what)
    if "meta_json" not in data:
        raise FileFormatError(
            f"{what} {path}: not a flexparcel results file (no 'meta_json' entry; it holds "
            f"{', '.join(sorted(data)) or 'no arrays'})"
        )
    try:
        meta = json.loads(str(data.pop("meta_json")))
    except json.JSONDecodeError as exc:
        raise FileFormatError(f"{what} {path}: its 'meta_json' is not valid JSON ({exc})") from exc
    if not isinstance(meta, dict) or meta.get("format") != "flexparcel-results":
        raise FileFormatError(f"{what} {path}: not a flexparcel results file")
    if meta.get("version") != RESULTS_FORMAT_VERSION:
        raise FileFormatError(
            f"{what} {path}: results format version {meta.get('version')!r}; this flexparcel "
            f"reads version {RESULTS_FORMAT_VERSION}"
        )
    missing = [k for k in ("time", "positions") if k not in data]
    if missing:
        raise FileFormatError(f"{what} {path}: missing array {', '.join(map(repr, missing))}")
    data["meta"] = meta
    return data
