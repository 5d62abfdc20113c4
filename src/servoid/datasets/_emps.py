"""The EMPS benchmark record (real servo axis, closed loop, friction)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from .._errors import MissingFileError
from ..data import Experiment, read_mat

__all__ = ["EMPS_CITATION", "emps_path", "load_emps"]

EMPS_CITATION = (
    "A. Janot, M. Gautier, M. Brunot, Data Set and Reference Models of EMPS, Workshop on "
    "Nonlinear System Identification Benchmarks, Eindhoven, 2019"
)
EMPS_SHA256 = "6cf6814ae14618795da0101aae2bb97ff0c6351b0501b5492751b02b07facf7e"


def emps_path() -> Path:
    """Path of the shipped ``DATA_EMPS.mat``.

    Returns
    -------
    pathlib.Path
        The file inside the installed package (see its ``PROVENANCE.md``).
    """
    resource = resources.files("servoid.datasets").joinpath("emps", "DATA_EMPS.mat")
    path = Path(str(resource))
    if not path.is_file():
        raise MissingFileError(
            f"the EMPS data file is missing from the installation ({path}); reinstall servoid "
            "with its package data"
        )
    return path


def load_emps() -> Experiment:
    """Load the EMPS record: reference, position, voltage and force.

    Channels: ``qg`` reference position [m] (role r), ``qm`` measured
    position [m] (role y), ``vir`` controller output [V] (role u, the plant
    input) and ``force`` = gtau·vir [N] (side channel). ``notes`` hold the
    scalars ``kp`` [1/s], ``kv`` [V/(m/s)], ``gtau`` [N/V], the voltage
    ``saturation`` [V] and the ``citation``. 24841 samples, dt ≈ 1 ms.

    Cite: Janot, Gautier, Brunot, *Data Set and Reference Models of EMPS*,
    Workshop on Nonlinear System Identification Benchmarks, 2019.

    Returns
    -------
    Experiment
        The record, named ``"EMPS"``.

    Examples
    --------
    >>> exp = load_emps()
    >>> exp.n_samples, exp.names
    (24841, ('qg', 'vir', 'qm', 'force'))
    >>> round(exp.notes["gtau"], 4)
    35.1507
    """
    raw = read_mat(emps_path(), variables=["qg", "qm", "vir"], time="t",
                   roles={"r": ["qg"], "u": ["vir"], "y": ["qm"]})
    gtau = float(raw.notes["gtau"])
    exp = raw.add_channel("force", gtau * raw["vir"], role="side", unit="N")
    units = {"qg": "m", "qm": "m", "vir": "V", "force": "N"}
    exp = exp.replace_channels(
        (ch.with_values(ch.values, units[ch.name]) for ch in exp.channels),
        name="EMPS",
        notes={
            "kp": float(raw.notes["kp"]),
            "kv": float(raw.notes["kv"]),
            "gtau": gtau,
            "saturation": 10.0,
            "citation": EMPS_CITATION,
            "sha256": EMPS_SHA256,
        },
    )
    return exp
