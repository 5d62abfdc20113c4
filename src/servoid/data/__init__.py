"""Experiments: signals of a test run, rig files, preprocessing.

The data pipeline is three records and one step: an :class:`ExperimentSpec`
(the TOML experiment file, plain data), :data:`RIG_FORMATS` (one
:class:`RigFormat` per rig-file format: extensions, reader, writer, the
keys it takes) and :func:`prepare`, which reads, calibrates, preprocesses
and splits, returning :class:`PreparedData` (the records, and each file
read with its SHA-256).

Each name is imported on first use, so that the command line lists the
rig-file formats (``--format``) without loading numpy.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ._csv import read_csv, write_csv
    from ._digest import file_sha256
    from ._experiment import ROLES, Channel, Experiment, ExperimentSet, Role, as_segments
    from ._formats import FORMATS, RIG_FORMATS, Format, RigFormat, read_experiment
    from ._intersample import IntersampleCheck, detect_intersample
    from ._mat import read_mat
    from ._prepare import InputFile, PreparedData, prepare
    from ._preprocess import (
        calibrate,
        decimate,
        detrend,
        filter,
        lowpass,
        split,
        split_periods,
    )
    from ._spec import (
        ChannelSpec,
        ExperimentSpec,
        PreprocessSpec,
        RigSpec,
        SplitSpec,
        ValidationSpec,
        load_experiment_spec,
        write_experiment_spec,
    )
    from ._tdms import read_tdms, write_tdms

__all__ = [
    "FORMATS",
    "RIG_FORMATS",
    "ROLES",
    "Channel",
    "ChannelSpec",
    "Experiment",
    "ExperimentSet",
    "ExperimentSpec",
    "Format",
    "InputFile",
    "IntersampleCheck",
    "PreparedData",
    "PreprocessSpec",
    "RigFormat",
    "RigSpec",
    "Role",
    "SplitSpec",
    "ValidationSpec",
    "as_segments",
    "calibrate",
    "decimate",
    "detect_intersample",
    "detrend",
    "file_sha256",
    "filter",
    "load_experiment_spec",
    "lowpass",
    "prepare",
    "read_csv",
    "read_experiment",
    "read_mat",
    "read_tdms",
    "split",
    "split_periods",
    "write_csv",
    "write_experiment_spec",
    "write_tdms",
]

#: the module that defines each export
_HOME = {
    "read_csv": "_csv", "write_csv": "_csv",
    "file_sha256": "_digest",
    "ROLES": "_experiment", "Channel": "_experiment", "Experiment": "_experiment",
    "ExperimentSet": "_experiment", "Role": "_experiment", "as_segments": "_experiment",
    "FORMATS": "_formats", "RIG_FORMATS": "_formats", "Format": "_formats",
    "RigFormat": "_formats", "read_experiment": "_formats",
    "IntersampleCheck": "_intersample", "detect_intersample": "_intersample",
    "read_mat": "_mat",
    "InputFile": "_prepare", "PreparedData": "_prepare", "prepare": "_prepare",
    "calibrate": "_preprocess", "decimate": "_preprocess", "detrend": "_preprocess",
    "filter": "_preprocess", "lowpass": "_preprocess", "split": "_preprocess",
    "split_periods": "_preprocess",
    "ChannelSpec": "_spec", "ExperimentSpec": "_spec", "PreprocessSpec": "_spec",
    "RigSpec": "_spec", "SplitSpec": "_spec", "ValidationSpec": "_spec",
    "load_experiment_spec": "_spec", "write_experiment_spec": "_spec",
    "read_tdms": "_tdms", "write_tdms": "_tdms",
}


def __getattr__(name: str) -> Any:
    """Import an export on first use."""
    if name not in _HOME:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_HOME[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
