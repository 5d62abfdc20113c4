"""Three real DaISy records: flexible robot arm, hair dryer, ball and beam."""

from __future__ import annotations

import hashlib
from importlib import resources
from pathlib import Path
from typing import Literal

import numpy as np

from .._errors import FileFormatError, MissingFileError, check_option
from ..data import Experiment

__all__ = ["DAISY_CITATION", "DAISY_RECORDS", "DaisyRecord", "daisy_path", "load_daisy"]

DaisyRecord = Literal["robot_arm", "dryer", "ballbeam"]
DAISY_RECORDS: tuple[DaisyRecord, ...] = ("robot_arm", "dryer", "ballbeam")
DAISY_CITATION = (
    "B. De Moor, P. De Gersem, B. De Schutter, W. Favoreel, DaISy: A database for "
    "identification of systems, Journal A 38(3), 1997"
)
# name: (sha256, dt [s] or None when the source gives none, input, output, what)
_RECORDS = {
    "robot_arm": ("7577818296239b7a47d1db59abac7ae03fe106f246e0a001152fcc0a733d83c7", None,
                  "torque", "acceleration", "flexible robot arm, open loop, periodic sine sweep"),
    "dryer": ("adcb2f5a1d9e174d08dd49f7f037626745b5e69cbda0bc1e8dca2a7c687d4538", 0.08,
              "heater", "temperature", "laboratory hair dryer, open loop"),
    "ballbeam": ("e9c48a4f7474953969d4950b4ef72558084b1995f776792ac0cbc80550e6ff42", 0.1,
                 "angle", "position", "ball and beam, under an undocumented controller"),
}


def daisy_path(name: DaisyRecord) -> Path:
    """Path of a shipped DaISy file.

    Parameters
    ----------
    name : {"robot_arm", "dryer", "ballbeam"}
        The record.

    Returns
    -------
    pathlib.Path
        The ``.dat`` file inside the installed package (see its ``PROVENANCE.md``).
    """
    check_option("name", name, DAISY_RECORDS)
    path = Path(str(resources.files("servoid.datasets").joinpath("daisy", f"{name}.dat")))
    if not path.is_file():
        raise MissingFileError(f"the DaISy file {path.name} is missing from the installation "
                               f"({path}); reinstall servoid with its package data")
    return path


def load_daisy(name: DaisyRecord) -> Experiment:
    """Load a DaISy record as an Experiment (input u, output y).

    ``robot_arm``: 1024 samples of torque → arm acceleration; the source
    gives no sampling period, so ``dt = 1`` (time in samples).
    ``dryer``: 1000 samples, dt = 0.08 s, heater voltage → outlet
    temperature sensor, open loop.  ``ballbeam``: 1000 samples, dt =
    0.1 s, beam angle → ball position, recorded under an undocumented
    controller (closed loop).  Units are not given by the source.

    Parameters
    ----------
    name : {"robot_arm", "dryer", "ballbeam"}
        The record.

    Returns
    -------
    Experiment
        Named after the record; ``notes`` hold the citation, the file's
        sha256 and whether dt came from the source.

    Examples
    --------
    >>> exp = load_daisy("dryer")
    >>> exp.n_samples, exp.dt, exp.names
    (1000, 0.08, ('heater', 'temperature'))
    """
    path = daisy_path(name)
    sha, dt, u_name, y_name, what = _RECORDS[name]
    raw = path.read_bytes()
    if hashlib.sha256(raw).hexdigest() != sha:
        raise FileFormatError(f"{path} does not match its published sha256; reinstall servoid")
    table = np.loadtxt(path)
    exp = Experiment.from_arrays(1.0 if dt is None else dt, u=table[:, 0], y=table[:, 1],
                                 names={"u": u_name, "y": y_name}, name=name)
    notes = {"citation": DAISY_CITATION, "sha256": sha, "record": what,
             "dt_source": "not given (dt = 1 sample)" if dt is None else "DaISy"}
    return exp.replace_channels(exp.channels, notes=notes)
