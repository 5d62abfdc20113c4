"""Excitation design: PRBS, random binary, multisine, chirp and steps.

Each designer returns an :class:`Excitation`, the samples plus the design
record (period, excited band, amplitude, clock), which converts to an
:class:`~servoid.data.Experiment` with :meth:`Excitation.to_experiment`.
:func:`prbs_clock` and :func:`prbs_register_for` apply the PRBS design
rules of models-spec §3.1; :func:`power_spectrum` and :func:`crest_factor`
check a design; :func:`largest_amplitude` applies the amplitude rule, the
largest amplitude a system's :class:`Limit` records allow.
"""

from ._binary import prbs, prbs_clock, prbs_length, prbs_register_for, random_binary
from ._excitation import Excitation, ExcitationRole
from ._lfsr import PRBS_TAPS
from ._limits import AmplitudeRule, Limit, largest_amplitude
from ._spectrum import Spectrum, SpectrumMethod, crest_factor, power_spectrum
from ._waveforms import ChirpMethod, Harmonics, MultisineScale, Phases, chirp, multisine, steps

__all__ = [
    "PRBS_TAPS",
    "AmplitudeRule",
    "ChirpMethod",
    "Excitation",
    "ExcitationRole",
    "Harmonics",
    "Limit",
    "MultisineScale",
    "Phases",
    "Spectrum",
    "SpectrumMethod",
    "chirp",
    "crest_factor",
    "largest_amplitude",
    "multisine",
    "power_spectrum",
    "prbs",
    "prbs_clock",
    "prbs_length",
    "prbs_register_for",
    "random_binary",
    "steps",
]
