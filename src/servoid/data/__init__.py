"""Experiments: signals of a test run, rig files, preprocessing."""

from ._experiment import ROLES, Channel, Experiment, ExperimentSet, Role, as_segments
from ._preprocess import calibrate, decimate, detrend, filter, lowpass, split, split_periods

__all__ = [
    "ROLES",
    "Channel",
    "Experiment",
    "ExperimentSet",
    "Role",
    "as_segments",
    "calibrate",
    "decimate",
    "detrend",
    "filter",
    "lowpass",
    "split",
    "split_periods",
]
