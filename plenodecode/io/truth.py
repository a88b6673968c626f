"""Ground-truth files of the synthetic generator: ``<name>.truth.json`` beside ``<name>.truth.npz``.

* ``<name>.truth.json``: one JSON document (``indent=1``) whose ``format`` is :data:`TRUTH_FORMAT` and
  ``version`` at most :data:`TRUTH_VERSION`, plus ``npz_arrays``: the names of the arrays in the npz;
* ``<name>.truth.npz``: the named arrays (``numpy.savez_compressed``).

This module reads and writes plain documents (dicts) and arrays only.  What goes into them (grid,
scene, preset, ...) and how they become a :class:`~plenodecode.synthetic.Truth` is
:mod:`plenodecode.synthetic.truth`'s business, so ``io`` never imports the generator.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import FormatError
from .atomic import atomic_output, refuse_existing, write_text_atomic

TRUTH_FORMAT = "plenodecode.SyntheticTruth"
TRUTH_VERSION = 1
#: Endings of the two files of a ground truth.
TRUTH_JSON_SUFFIX = ".truth.json"
TRUTH_NPZ_SUFFIX = ".truth.npz"


def truth_npz_path(json_path: str | os.PathLike) -> Path:
    """The ``.truth.npz`` that belongs to ``<name>.truth.json``."""
    p = Path(json_path)
    return p.with_name(p.name[: -len(".json")] + ".npz")


def write_truth(json_path: str | os.PathLike, document: Mapping[str, Any], arrays: Mapping[str, np.ndarray], *,
                overwrite: bool = False) -> tuple[Path, Path]:
    """Write a ground truth: the ``arrays`` into ``<name>.truth.npz``, then ``document`` (with ``npz_arrays``,
    the sorted array names, appended) into ``json_path`` = ``<name>.truth.json``.

    Each file is written to a temporary name and renamed; the npz comes first, so a truth JSON never names
    an npz that is not there.

    Parameters
    ----------
    json_path : path-like
        Ends in ``.truth.json``.
    document : mapping
        JSON-serialisable; written in its key order.
    arrays : mapping of str -> ndarray
        Any shapes and dtypes ``numpy.savez_compressed`` stores, in this order.
    overwrite : bool
        Replace existing files (else FileExistsError).

    Returns
    -------
    (Path, Path)
        The JSON and the npz.
    """
    p = Path(json_path)
    if not p.name.endswith(TRUTH_JSON_SUFFIX):
        raise ValueError(f"json_path must end in {TRUTH_JSON_SUFFIX}, got {p.name!r}")
    npz = truth_npz_path(p)
    refuse_existing([npz, p], overwrite)                 # both checked before either is written
    with atomic_output(npz, overwrite=overwrite) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
    doc = {**document, "npz_arrays": sorted(arrays)}
    write_text_atomic(p, json.dumps(doc, indent=1), overwrite=overwrite)
    return p, npz


def find_truth_json(path: str | os.PathLike) -> Path:
    """The ``.truth.json`` meant by ``path``: that file, the JSON of a ``.truth.npz``, or the only
    ``*.truth.json`` in a folder.

    Raises
    ------
    FormatError
        A folder without exactly one, or a missing file.
    """
    p = Path(path)
    if p.is_dir():
        found = sorted(p.glob("*" + TRUTH_JSON_SUFFIX))
        if len(found) != 1:
            raise FormatError(f"{p}: expected exactly one *{TRUTH_JSON_SUFFIX}, found {len(found)}; "
                              "pass the file itself")
        p = found[0]
    if p.name.endswith(TRUTH_NPZ_SUFFIX):
        p = p.with_name(p.name[: -len(".npz")] + ".json")
    if not p.is_file():
        raise FormatError(f"{p}: no such ground-truth file; pass the .truth.json written by write_simulation")
    return p


def read_truth(path: str | os.PathLike) -> tuple[dict[str, Any], dict[str, np.ndarray], Path]:
    """Read a ground truth (``path`` as for :func:`find_truth_json`).

    Returns
    -------
    document : dict
        The JSON document.
    arrays : dict of str -> ndarray
        Every array of the npz.
    json_path : Path
        The ``.truth.json`` read.

    Raises
    ------
    FormatError
        Missing files, unreadable JSON, another ``format``, a newer ``version``, or no npz beside it.
    """
    p = find_truth_json(path)
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FormatError(f"{p}: not readable JSON ({exc}); pass a .truth.json written by write_simulation") from exc
    if not isinstance(doc, dict) or doc.get("format") != TRUTH_FORMAT:
        raise FormatError(f"{p}: format is {doc.get('format') if isinstance(doc, dict) else None!r}, expected "
                          f"{TRUTH_FORMAT!r}; pass a .truth.json written by write_simulation")
    if int(doc.get("version", 0)) > TRUTH_VERSION:
        raise FormatError(f"{p}: truth version {doc.get('version')} is newer than {TRUTH_VERSION}; upgrade plenodecode")
    npz = truth_npz_path(p)
    if not npz.is_file():
        raise FormatError(f"{npz}: missing; the .truth.json and .truth.npz must stay together")
    with np.load(npz) as z:
        arrays = {k: z[k] for k in z.files}
    return doc, arrays, p


__all__ = ["TRUTH_FORMAT", "TRUTH_VERSION", "TRUTH_JSON_SUFFIX", "TRUTH_NPZ_SUFFIX", "truth_npz_path", "write_truth",
           "find_truth_json", "read_truth"]
