"""Records an experiment file lists more than once, by content.

A record listed twice in ``[data] file`` is fitted as two independent
records: the parameter intervals shrink by √2 with no new information. A
``[validation] file`` that holds the estimation samples is scored as "data
not used for fitting" although it was. Paths do not tell (a copy under
another name, the same file by another path), so records are compared by
a digest of their samples after reading, calibration and preprocessing.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from .._errors import FileFormatError
from ._experiment import Experiment

__all__ = ["check_distinct", "record_fingerprint"]


def check_distinct(origin: str, paths: tuple[Path, ...], parts: tuple[Experiment, ...],
                    val_paths: tuple[Path, ...], validations: tuple[Experiment, ...]) -> None:
    """Refuse a record listed twice, or a validation record that is estimation data.

    Parameters
    ----------
    origin : str
        The experiment file, as messages name it.
    paths, val_paths : tuple of pathlib.Path
        The estimation and validation files.
    parts, validations : tuple of Experiment
        Their records, read and preprocessed (not detrended).

    Raises
    ------
    FileFormatError
        Two estimation records, two validation records, or a validation
        and an estimation record with the same samples.
    """
    seen: dict[str, Path] = {}
    for path, exp in zip(paths, parts, strict=True):
        key = record_fingerprint(exp)
        if key in seen:
            raise FileFormatError(
                f"{origin}: [data] file lists the same record twice: {seen[key]} and {path} "
                "hold the same samples. Fitted twice, one record counts as two independent "
                "ones and the intervals shrink by √2 without any new information: list each "
                "record once"
            )
        seen[key] = path
    checked: dict[str, Path] = {}
    for path, exp in zip(val_paths, validations, strict=True):
        key = record_fingerprint(exp)
        if key in seen:
            raise FileFormatError(
                f"{origin}: [validation] file {path} holds the same samples as the estimation "
                f"record {seen[key]}: a validation on the data the model was fitted to says "
                "nothing about new data, yet the report would call it data not used for "
                "fitting. Name a record that was not used for fitting, or remove "
                "[validation] to split the estimation record into two parts"
            )
        if key in checked:
            raise FileFormatError(
                f"{origin}: [validation] file lists the same record twice: {checked[key]} "
                f"and {path} hold the same samples: list each record once"
            )
        checked[key] = path


def record_fingerprint(exp: Experiment) -> str:
    """A digest of a record's samples and sampling (BLAKE2b of the raw values).

    Parameters
    ----------
    exp : Experiment
        The record.

    Returns
    -------
    str
        Hex digest; two records with the same digest hold the same samples
        at the same period, whatever their names or files.
    """
    digest = hashlib.blake2b(digest_size=20)
    digest.update(np.float64(exp.dt).tobytes())
    digest.update(np.int64(exp.n_samples).tobytes())
    for ch in sorted(exp.channels, key=lambda c: c.name):
        digest.update(ch.name.encode() + b"\0")
        digest.update(np.ascontiguousarray(ch.values, dtype=float))
    return digest.hexdigest()
