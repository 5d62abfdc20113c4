"""The rig description: actuator, fidelity, DAQ, sensors.

:class:`EhsaBench` is a frozen record of everything that sets what the
virtual rig writes: the actuator's physical parameters and model
fidelity, the DAQ (acquisition rate, analog anti-alias filter, converter
bits and range), the transducers' sensitivities and the sensor noise.
Defaults that depend on other fields (the anti-alias cutoff, the
sensitivities) are resolved on construction, so ``repr`` and ``==`` show
the values used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from ..._errors import DataError, OptionTypeError, check_option
from ...bench import butterworth
from ...models import TransferFunction
from .._common import integer_field, positive_field, real_field
from ._params import SET_B, EhsaParameters

__all__ = ["FIDELITIES", "REFERENCES", "EhsaBench", "Fidelity", "Reference"]

Fidelity = Literal["reduced", "full", "nonlinear"]
#: The actuator models the bench can run.
FIDELITIES: tuple[Fidelity, ...] = ("reduced", "full", "nonlinear")
Reference = Literal["readback", "command"]
#: How the rig logs the reference.
REFERENCES: tuple[Reference, ...] = ("readback", "command")

_BITS = (8, 24)
_AA_ORDERS = (1, 10)
_COMMAND_RANGE = 0.023  # [m] ±23 mm command [S1] (printed)
_P_FULL_SCALE = 35e6  # [Pa] pressure transducers 0–35 MPa → 0–10 V
_T_SENSITIVITY = 0.1  # [V/°C] 10 V at 100 °C
#: Record [s] of the impulse responses that size the noise budget (bench._run).
NOISE_GAIN_SPAN = 0.1
#: Largest array the noise budget may build [bytes]: its impulse responses, m·q of them
#: over NOISE_GAIN_SPAN at the analog rate, grow as f_acq·(f_acq/f_s); filtering and
#: decimating them takes about three times this.
MAX_NOISE_GAIN_BYTES = 2**29


@dataclass(frozen=True)
class EhsaBench:
    """A virtual EHSA test rig: actuator, DAQ, transducers, noise.

    Signal chain of one channel: analog signal at ``oversample·f_acq`` →
    Butterworth anti-alias filter → sample at `f_acq` → ADC (`bits`,
    ±`adc_range`, clipped).  The command is played by the DAQ's DAC at
    `f_acq` (zero-order hold, same bits and range) and either read back
    through the same filter (``reference="readback"``: the reference and
    the position share the filter's phase lag, a band-limited reference) or
    logged as the codes written to the DAC (``reference="command"``: a
    staircase; the position alone carries the filter, which the experiment
    file then declares).

    Parameters
    ----------
    params : EhsaParameters
        Physical parameters of the actuator; default :data:`SET_B`.
    fidelity : {"reduced", "full", "nonlinear"}
        ``"reduced"``: the third-order loop ``c·G_simple/(1 + F·G_simple)``
        ([S1] Eq. 11, the structure the identification assumes, so its K,
        ω_hp, δ_hp are the truth); ``"full"``: the eighth-order linear loop;
        ``"nonlinear"``: :func:`~servoid.plants.ehsa.simulate_ehsa` (flow
        law, saturations, friction, dead time ``params.T_d``).
    f_acq : float
        Acquisition rate of the DAQ [Hz], an integer multiple of `f_s`.
        Sizing the noise takes about ``0.1·f_acq·oversample²·(f_acq/f_s)``
        doubles, which must fit in 512 MiB: up to about 8 MHz at the
        default ratio 5 and oversample 4.
    f_s : float
        Identification rate [Hz]: the excitation is designed at it and the
        experiment file decimates to it.
    aa_order : int
        Order of the analog Butterworth anti-alias filter, 1..10.
    aa_cutoff : float, optional
        Its -3 dB frequency [Hz], below ``f_acq/2``.  Default
        ``0.2·f_acq`` (1 kHz at 5 kHz): what folds onto the band kept after
        decimation (0..f_s/2) lies at ``f_acq ± f_s/2`` and above, >= 52 dB
        down for the 4th order, while at ``f_s/2`` the gain is within
        0.02 dB of 1; the filter's lag (0.42 ms group delay at DC) is the
        same on every channel.
    bits : int
        Resolution of the ADC and DAC, 8..24; the step is
        ``2·adc_range/2**bits``.
    adc_range : float
        Input (and output) range ±`adc_range` [V], > 0; codes beyond are
        clipped.
    position_sensitivity : float, optional
        Position transducer [V/m]; default ``adc_range/params.stroke``
        (the mechanical stroke fills the range: 400 V/m).
    command_sensitivity : float, optional
        Scale of the command voltage [V/m], the driver's input scale;
        default ``adc_range/command_range`` (±23 mm ↔ ±10 V ↔ ±50 mA).
    command_range : float
        Largest commanded position ±[m], > 0. [S1] 23 mm.
    snr_db : float or None
        Signal-to-noise ratio of the position that identification sees
        (decimated to `f_s`) [dB]: ``20·log10(rms(y − ȳ)/σ_e)`` with σ_e
        the standard deviation of sensor plus quantisation noise there.
        The sensor noise is white at the analog rate, added before the
        anti-alias filter; its level is set so that the total at `f_s`
        meets `snr_db`.  None: no sensor noise (quantisation only).
    oversample : int
        Analog simulation rate as a multiple of `f_acq`, >= 1 (default 4:
        20 kHz); sensor noise is white up to half of it, so the
        anti-alias filter has something to remove.
    p_supply_sensitivity, p_return_sensitivity : float, optional
        Pressure transducers [V/Pa]; default 0–35 MPa → 0–10 V.
    temperature_sensitivity : float
        Oil temperature sensor [V/°C]; default 0.1 (10 V at 100 °C).
    oil_temperature : float
        Oil temperature at the start of the run [°C].
    reference : {"readback", "command"}
        How the rig file logs the reference: read back through the
        anti-alias filter and ADC like the position, or as the DAC command
        itself (no filter, no noise).

    Examples
    --------
    >>> bench = EhsaBench()
    >>> bench.decimation, bench.aa_cutoff, round(bench.lsb * 1e6, 1)
    (5, 1000.0, 305.2)
    """

    params: EhsaParameters = SET_B
    fidelity: Fidelity = "reduced"
    f_acq: float = 5000.0
    f_s: float = 1000.0
    aa_order: int = 4
    aa_cutoff: float | None = None
    bits: int = 16
    adc_range: float = 10.0
    position_sensitivity: float | None = None
    command_sensitivity: float | None = None
    command_range: float = _COMMAND_RANGE
    snr_db: float | None = 30.0
    oversample: int = 4
    p_supply_sensitivity: float | None = None
    p_return_sensitivity: float | None = None
    temperature_sensitivity: float = _T_SENSITIVITY
    oil_temperature: float = 40.0
    reference: Reference = "readback"

    def __post_init__(self) -> None:
        if not isinstance(self.params, EhsaParameters):
            raise OptionTypeError(f"params must be EhsaParameters, "
                                  f"got {type(self.params).__name__}")
        check_option("fidelity", self.fidelity, FIDELITIES)
        check_option("reference", self.reference, REFERENCES)
        f_acq = positive_field("f_acq", self.f_acq, "Hz")
        f_s = positive_field("f_s", self.f_s, "Hz")
        ratio = f_acq / f_s
        if ratio < 1 - 1e-9 or abs(ratio - round(ratio)) > 1e-9 * ratio:
            hint = max(1, math.ceil(ratio)) * f_s
            raise DataError(
                f"f_acq = {f_acq:g} Hz must be an integer multiple of f_s = {f_s:g} Hz (the "
                f"decimation factor); try f_acq = {hint:g} Hz"
            )
        _set(self, "f_acq", f_acq)
        _set(self, "f_s", f_s)
        _set(self, "aa_order", integer_field("aa_order", self.aa_order, *_AA_ORDERS))
        cutoff = 0.2 * f_acq if self.aa_cutoff is None else positive_field(
            "aa_cutoff", self.aa_cutoff, "Hz")
        if cutoff >= f_acq / 2:
            raise DataError(
                f"aa_cutoff must lie below the acquisition Nyquist frequency f_acq/2 = "
                f"{f_acq / 2:g} Hz, got {cutoff:g} Hz; the default is 0.2·f_acq"
            )
        _set(self, "aa_cutoff", cutoff)
        _set(self, "bits", integer_field("bits", self.bits, *_BITS))
        adc = positive_field("adc_range", self.adc_range, "V")
        _set(self, "adc_range", adc)
        _set(self, "command_range", positive_field("command_range", self.command_range, "m"))
        defaults = {
            "position_sensitivity": adc / self.params.stroke,
            "command_sensitivity": adc / self.command_range,
            "p_supply_sensitivity": 10.0 / _P_FULL_SCALE,
            "p_return_sensitivity": 10.0 / _P_FULL_SCALE,
        }
        units = {"position_sensitivity": "V/m", "command_sensitivity": "V/m",
                 "p_supply_sensitivity": "V/Pa", "p_return_sensitivity": "V/Pa"}
        for name, default in defaults.items():
            value = getattr(self, name)
            _set(self, name, default if value is None else positive_field(name, value, units[name]))
        _set(self, "temperature_sensitivity",
             positive_field("temperature_sensitivity", self.temperature_sensitivity, "V/°C"))
        if self.snr_db is not None:
            snr = real_field("snr_db", self.snr_db, "dB")
            if not math.isfinite(snr):
                raise DataError(
                    f"snr_db must be finite [dB], got {snr}; pass snr_db=None for no sensor noise"
                )
            _set(self, "snr_db", snr)
        _set(self, "oversample", integer_field("oversample", self.oversample, 1, 64))
        temp = real_field("oil_temperature", self.oil_temperature, "°C")
        if not math.isfinite(temp):
            raise DataError(f"oil_temperature must be finite [°C], got {temp}")
        _set(self, "oil_temperature", temp)
        self._check_rates()

    def _check_rates(self) -> None:
        """Refuse rates whose noise budget would not fit in memory."""
        q, m = self.decimation, self.oversample
        n, columns = noise_gain_shape(self.f_acq, q, m)
        need = 8.0 * n * columns
        if need <= MAX_NOISE_GAIN_BYTES:
            return
        # n·columns ≈ NOISE_GAIN_SPAN·f_acq·m²·q floats: what fits at this ratio, at this f_acq
        floats = MAX_NOISE_GAIN_BYTES / (8.0 * NOISE_GAIN_SPAN * m * m)
        fits = []
        if floats / q >= q:  # f_s >= 1 Hz
            fits.append(f"f_acq <= {0.99 * floats / q:.3g} Hz at f_acq/f_s = {q}")
        if floats / self.f_acq >= 1:
            fits.append(f"f_acq/f_s <= {math.floor(floats / self.f_acq)} at f_acq = "
                        f"{self.f_acq:g} Hz")
        advice = "rates that fit: " + ", or ".join(fits) if fits else "lower f_acq"
        raise DataError(
            f"f_s = {self.f_s:g} Hz with f_acq = {self.f_acq:g} Hz is beyond what the virtual "
            f"rig can simulate: sizing its noise takes {m * q:,} impulse responses of {n:,} "
            f"samples at oversample·f_acq ({_gib(need)} GiB), over the "
            f"{_gib(MAX_NOISE_GAIN_BYTES)} GiB budget; {advice} (a servo rig samples at kHz to "
            "a few hundred kHz)"
        )

    @property
    def decimation(self) -> int:
        """Decimation factor ``f_acq/f_s``."""
        return round(self.f_acq / self.f_s)

    @property
    def dt(self) -> float:
        """Identification sample period ``1/f_s`` [s]."""
        return 1.0 / self.f_s

    @property
    def dt_acq(self) -> float:
        """Acquisition sample period ``1/f_acq`` [s]."""
        return 1.0 / self.f_acq

    @property
    def lsb(self) -> float:
        """Converter step ``2·adc_range/2**bits`` [V]."""
        return 2.0 * self.adc_range / 2**self.bits

    @property
    def c(self) -> float:
        """Reference gain ``K_TM·K_driver`` of the loop [m/m]."""
        return self.params.reference_gain

    @property
    def F(self) -> float:
        """Feedback gain ``K_fb`` of the loop [m/m]."""
        return self.params.K_fb

    def resolution_note(self) -> str:
        """Return why `f_s` cannot resolve the resonance, or "" when it can.

        The hydraulic resonance ω_hp counts as resolved when the Nyquist
        frequency ``π·f_s`` is at least twice it (``f_s >= 4·f_hp``), the
        rule :func:`servoid.plants.ehsa.fit_one_step` flags results by.

        Returns
        -------
        str
            A warning naming the rate that would resolve it, or "".
        """
        w = self.params.omega_hp
        if 2.0 * w <= math.pi * self.f_s:
            return ""
        f_hp = w / (2.0 * math.pi)
        needed = _round_up(4.0 * f_hp)
        return (
            f"f_s = {self.f_s:g} Hz cannot resolve this actuator's hydraulic resonance "
            f"omega_hp = {w:.5g} rad/s ({f_hp:.4g} Hz): the Nyquist frequency "
            f"{math.pi * self.f_s:.4g} rad/s is less than twice it, so the identification "
            f"will flag omega_hp and delta_hp as unresolved; use f_s >= {needed:g} Hz "
            f"(4·f_hp), e.g. --fs {needed:g} --facq {5 * needed:g}"
        )

    def anti_alias(self) -> TransferFunction:
        """Return the analog anti-alias filter.

        Returns
        -------
        TransferFunction
            Continuous Butterworth of order `aa_order` at `aa_cutoff`.
        """
        assert self.aa_cutoff is not None  # resolved in __post_init__
        return butterworth(self.aa_order, self.aa_cutoff)


def noise_gain_shape(f_acq: float, q: int, m: int) -> tuple[int, int]:
    """Shape of the impulse array of the noise budget: (samples, impulses).

    ``m·q`` impulses at consecutive positions of a record of
    :data:`NOISE_GAIN_SPAN` at the analog rate ``m·f_acq``, a whole
    number of decimated samples long.
    """
    return m * q * math.ceil(NOISE_GAIN_SPAN * f_acq / q), m * q


# -- private helpers ---------------------------------------------------------


def _gib(n: float) -> str:
    return f"{n / 2**30:.3g}"


def _round_up(value: float) -> float:
    """Round up to two significant digits (a rate to ask for)."""
    scale = 10.0 ** (math.floor(math.log10(value)) - 1)
    return math.ceil(value / scale) * scale


def _set(obj: EhsaBench, name: str, value: object) -> None:
    object.__setattr__(obj, name, value)

