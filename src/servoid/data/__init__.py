"""Experiments: signals of a test run, rig files, preprocessing."""

from ._csv import read_csv, write_csv
from ._experiment import ROLES, Channel, Experiment, ExperimentSet, Role, as_segments
from ._intersample import IntersampleCheck, detect_intersample
from ._io import FORMATS, Format, read_experiment
from ._mat import read_mat
from ._preprocess import calibrate, decimate, detrend, filter, lowpass, split, split_periods
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
    "ROLES",
    "Channel",
    "ChannelSpec",
    "Experiment",
    "ExperimentSet",
    "ExperimentSpec",
    "Format",
    "IntersampleCheck",
    "PreprocessSpec",
    "RigSpec",
    "Role",
    "SplitSpec",
    "ValidationSpec",
    "as_segments",
    "calibrate",
    "decimate",
    "detect_intersample",
    "detrend",
    "filter",
    "load_experiment_spec",
    "lowpass",
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
