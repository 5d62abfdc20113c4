"""The Wiener–Hammerstein benchmark record (SYSID 2009): a real circuit, filter–diode–filter."""

from __future__ import annotations

import hashlib
from importlib import resources
from pathlib import Path
from typing import Literal

import numpy as np

from .._errors import FileFormatError, MissingFileError, check_option
from ..data import Experiment, read_mat

__all__ = ["WH_CITATION", "WH_PARTS", "WhPart", "load_wiener_hammerstein",
           "wiener_hammerstein_path"]

WH_CITATION = (
    "J. Schoukens, J. Suykens, L. Ljung, Wiener-Hammerstein benchmark, 15th IFAC Symposium on "
    "System Identification (SYSID 2009), Saint-Malo, 2009"
)
WhPart = Literal["estimation", "test"]
WH_PARTS: tuple[WhPart, ...] = ("estimation", "test")
#: sha256 of the original WienerHammerBenchmark.csv the parts were cut from.
_ORIGINAL_SHA256 = "95f241ac5e0afb48c47b24b3630f55e0d6f8f2f4dec145bd8adf852b19851fa3"
# part: (file, samples, sha256 of the (N, 2) float64 little-endian array [u, y])
_PARTS = {
    "estimation": ("wh_estimation.mat", 100_000,
                   "9adb2a1fb1c56c7d8ef821f1d6d196261a8d031ba3616fd66179ab87c9ed477a"),
    "test": ("wh_test.mat", 78_800,
             "b7b71bdbecf70062de792e4415d27bc06092b1be95c62e5363913f2ad971a1ef"),
}
#: The record's sample period [s]: 51 200 Hz.
_DT = 1 / 51200.0


def wiener_hammerstein_path(part: WhPart = "estimation") -> Path:
    """Path of a shipped Wiener–Hammerstein benchmark part.

    Parameters
    ----------
    part : {"estimation", "test"}
        The benchmark's estimation part (100 000 samples) or test part
        (78 800 samples).

    Returns
    -------
    pathlib.Path
        The compressed MAT file inside the installed package (see its
        ``PROVENANCE.md``); the experiment file reads it directly.
    """
    check_option("part", part, WH_PARTS)
    name = _PARTS[part][0]
    path = Path(str(resources.files("servoid.datasets").joinpath("wiener_hammerstein", name)))
    if not path.is_file():
        raise MissingFileError(f"the Wiener–Hammerstein file {name} is missing from the "
                               f"installation ({path}); reinstall servoid with its package data")
    return path


def load_wiener_hammerstein(part: WhPart = "estimation") -> Experiment:
    """Load a part of the Wiener–Hammerstein benchmark (SYSID 2009).

    A real electronic circuit: a linear filter, a diode-based static
    nonlinearity and a second filter, excited by filtered Gaussian noise,
    sampled at 51 200 Hz. Channels ``u`` (input voltage [V], role u) and
    ``y`` (output voltage [V], role y). The parts are the benchmark's split:
    samples [5200:105200] and [105200:184000] of the original record; the
    benchmark scores the free run on the test part after its first 50
    samples (which may be used for the initial state).

    Cite: Schoukens, Suykens, Ljung, *Wiener–Hammerstein benchmark*,
    SYSID 2009.

    Parameters
    ----------
    part : {"estimation", "test"}
        The estimation part (100 000 samples) or the test part (78 800).

    Returns
    -------
    Experiment
        Named ``"WH_estimation"`` or ``"WH_test"``; ``notes`` hold the
        citation, the original file's sha256 and the part's place in it.

    Raises
    ------
    FileFormatError
        The shipped file's samples do not match their recorded sha256.

    Examples
    --------
    >>> exp = load_wiener_hammerstein("test")
    >>> exp.n_samples, exp.dt, exp.names
    (78800, 1.953125e-05, ('u', 'y'))
    """
    check_option("part", part, WH_PARTS)
    path = wiener_hammerstein_path(part)
    _, n, sha = _PARTS[part]
    exp = read_mat(path, variables=["u", "y"], dt=_DT, roles={"u": ["u"], "y": ["y"]})
    table = np.column_stack([exp["u"], exp["y"]]).astype("<f8")
    if table.shape != (n, 2) or hashlib.sha256(table.tobytes()).hexdigest() != sha:
        raise FileFormatError(f"{path} does not hold the benchmark's {part} samples (its sha256 "
                              "differs); reinstall servoid")
    channels = [ch.with_values(ch.values, "V") for ch in exp.channels]
    first = 5200 if part == "estimation" else 105_200
    notes = {"citation": WH_CITATION, "sha256_original": _ORIGINAL_SHA256,
             "samples": f"[{first}:{first + n}] of WienerHammerBenchmark.csv"}
    return exp.replace_channels(channels, name=f"WH_{part}", notes=notes)
