"""The EMPS benchmark records (real servo axis, closed loop, friction)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Literal

from .._errors import MissingFileError, check_option
from ..data import Experiment, read_mat

__all__ = ["EMPS_CITATION", "emps_path", "load_emps"]

EMPS_CITATION = (
    "A. Janot, M. Gautier, M. Brunot, Data Set and Reference Models of EMPS, Workshop on "
    "Nonlinear System Identification Benchmarks, Eindhoven, 2019"
)
EmpsRecord = Literal["estimation", "validation"]
EMPS_RECORDS: tuple[EmpsRecord, ...] = ("estimation", "validation")
_FILES = {"estimation": "DATA_EMPS.mat", "validation": "DATA_EMPS_PULSES.mat"}
_SHA256 = {
    "estimation": "6cf6814ae14618795da0101aae2bb97ff0c6351b0501b5492751b02b07facf7e",
    "validation": "0eab75bb1f6b16228ee78791343a88bf9bfd9a51036ac9807d7b5fc11c0e1704",
}
EMPS_SHA256 = _SHA256["estimation"]


def emps_path(record: EmpsRecord = "estimation") -> Path:
    """Path of a shipped EMPS file.

    Parameters
    ----------
    record : {"estimation", "validation"}
        ``DATA_EMPS.mat`` (the estimation record) or
        ``DATA_EMPS_PULSES.mat`` (the validation record, with force pulses).

    Returns
    -------
    pathlib.Path
        The file inside the installed package (see its ``PROVENANCE.md``).
    """
    check_option("record", record, EMPS_RECORDS)
    resource = resources.files("servoid.datasets").joinpath("emps", _FILES[record])
    path = Path(str(resource))
    if not path.is_file():
        raise MissingFileError(
            f"the EMPS data file is missing from the installation ({path}); reinstall servoid "
            "with its package data"
        )
    return path


def load_emps(record: EmpsRecord = "estimation") -> Experiment:
    """Load an EMPS record: reference, position, voltage and force.

    Channels: ``qg`` reference position [m] (role r), ``qm`` measured
    position [m] (role y), ``vir`` controller output [V] (role u, the plant
    input) and ``force`` = gtau·vir [N] (side channel). The validation
    record adds ``pulses`` [V], the square wave added to the controller
    output (the file's ``pulses_N``, which despite its name is in volts:
    ``vir`` contains it), and ``pulse_force`` = gtau·pulses [N], the
    disturbance force on the axis. ``notes`` hold the scalars ``kp``
    [1/s], ``kv`` [V/(m/s)], ``gtau`` [N/V], the voltage ``saturation``
    [V], the ``citation`` and the file's ``sha256``. 24841 samples each,
    dt ≈ 1 ms.

    Cite: Janot, Gautier, Brunot, *Data Set and Reference Models of EMPS*,
    Workshop on Nonlinear System Identification Benchmarks, 2019.

    Parameters
    ----------
    record : {"estimation", "validation"}
        ``DATA_EMPS.mat`` or ``DATA_EMPS_PULSES.mat``.

    Returns
    -------
    Experiment
        The record, named ``"EMPS"`` or ``"EMPS_PULSES"``.

    Examples
    --------
    >>> exp = load_emps()
    >>> exp.n_samples, exp.names
    (24841, ('qg', 'vir', 'qm', 'force'))
    >>> round(exp.notes["gtau"], 4)
    35.1507
    >>> load_emps("validation").names
    ('qg', 'vir', 'qm', 'force', 'pulses', 'pulse_force')
    """
    path = emps_path(record)
    pulses = record == "validation"
    variables = ["qg", "qm", "vir", *(["pulses_N"] if pulses else [])]
    raw = read_mat(path, variables=variables, time="t",
                   roles={"r": ["qg"], "u": ["vir"], "y": ["qm"]})
    gtau = float(raw.notes["gtau"])
    exp = raw.add_channel("force", gtau * raw["vir"], role="side", unit="N")
    units = {"qg": "m", "qm": "m", "vir": "V", "force": "N"}
    channels = [ch.with_values(ch.values, units[ch.name]) for ch in exp.channels
                if ch.name in units]
    exp = exp.replace_channels(
        channels,
        name="EMPS_PULSES" if pulses else "EMPS",
        notes={
            "kp": float(raw.notes["kp"]),
            "kv": float(raw.notes["kv"]),
            "gtau": gtau,
            "saturation": 10.0,
            "citation": EMPS_CITATION,
            "sha256": _SHA256[record],
        },
    )
    if pulses:
        volts = raw["pulses_N"]
        exp = exp.add_channel("pulses", volts, role="side", unit="V")
        exp = exp.add_channel("pulse_force", gtau * volts, role="side", unit="N")
    return exp
