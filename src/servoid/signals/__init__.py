"""Excitation design: PRBS, random binary, multisine, chirp and steps.

Each designer returns an :class:`Excitation`, the samples plus the design
record (period, excited band, amplitude, clock), which converts to an
:class:`~servoid.data.Experiment` with :meth:`Excitation.to_experiment`.
:func:`prbs_clock` and :func:`prbs_register_for` apply the PRBS design
rules of models-spec §3.1; :func:`power_spectrum` and :func:`crest_factor`
check a design; :func:`largest_amplitude` applies the amplitude rule, the
largest amplitude a system's :class:`Limit` records allow.
:func:`plan_multisine` plans a test of M random-phase multisine
realisations × P periods (full, odd or random-odd lines with detection
lines), :func:`random_multisine` draws it and :func:`read_plan` reads the
plan file written beside the DAQ file.
"""

from ._binary import prbs, prbs_clock, prbs_length, prbs_register_for, random_binary
from ._excitation import Excitation, ExcitationRole
from ._lfsr import PRBS_TAPS
from ._limits import AmplitudeRule, Limit, largest_amplitude
from ._multisine_design import (
    CrestMethod,
    LineGrid,
    LineSet,
    MultisinePlan,
    plan_multisine,
    random_multisine,
    read_plan,
)
from ._spectrum import Spectrum, SpectrumMethod, crest_factor, power_spectrum
from ._waveforms import ChirpMethod, Harmonics, MultisineScale, Phases, chirp, multisine, steps

# isort: split
# Building blocks other servoid packages import (through this package, not its modules);
# not part of the public API (__all__).
from ._checks import MAX_SAMPLES as MAX_SAMPLES

__all__ = [
    "PRBS_TAPS",
    "AmplitudeRule",
    "ChirpMethod",
    "CrestMethod",
    "Excitation",
    "ExcitationRole",
    "Harmonics",
    "Limit",
    "LineGrid",
    "LineSet",
    "MultisinePlan",
    "MultisineScale",
    "Phases",
    "Spectrum",
    "SpectrumMethod",
    "chirp",
    "crest_factor",
    "largest_amplitude",
    "multisine",
    "plan_multisine",
    "power_spectrum",
    "prbs",
    "prbs_clock",
    "prbs_length",
    "prbs_register_for",
    "random_binary",
    "random_multisine",
    "read_plan",
    "steps",
]
