"""Run an excitation on the virtual EHSA rig.

The chain, per sample period ``1/f_acq`` of the DAQ:

1. DAC: the excitation (designed at ``f_s``, metres of commanded
   position) is repeated ``f_acq/f_s`` times (zero-order hold), scaled by
   the driver's input scale [V/m] and quantised; the actuator is driven
   by exactly that staircase.
2. Actuator, simulated at the analog rate ``oversample·f_acq``: the
   reduced or full linear loop (exact zero-order-hold discretisation of a
   balanced cascade realisation) or the nonlinear simulator.
3. Transducers: position [V/m], supply and return pressure [V/Pa], oil
   temperature [V/°C].  White sensor noise at the analog rate is added
   to the position before the anti-alias filter, sized by the noise
   budget below; the side channels carry their own small noise, the
   supply a pump ripple and the temperature a slow drift (constants
   below).
4. The analog Butterworth anti-alias filter on every channel (exact for
   the command staircase, first-order hold for the smooth signals),
   sampling at ``f_acq`` and quantisation with clipping.  With
   ``reference="command"`` the reference channel is instead the DAC's
   codes as written: the staircase itself, without filter or noise.

Noise budget.  With ``g_s`` the gain of the chain filter → sample →
decimate (the decimation of :func:`servoid.data.decimate`) for white
noise at the analog rate and ``g_q`` that of the decimation for the
quantisation noise (``LSB²/12``, white at ``f_acq``), the sensor noise
standard deviation σ is chosen so that ``σ²g_s² + (LSB²/12)g_q²`` [m²,
after the transducer scale] equals ``(rms(y − ȳ)/10^(SNR/20))²``, the
clean position being decimated the same way.  So the SNR refers to the
``f_s`` data identification sees and counts quantisation in.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._errors import DataError, OptionTypeError, check_option
from ..._lazy import signal as sps
from ...bench import Hold, discrete_sos, discretise, note_warning, quantise, realise, resolve_rng
from ...data import Channel, Experiment, decimate
from ...models import StateSpace, TransferFunction
from ...signals import Excitation
from ._bench_config import EhsaBench, Fidelity, noise_gain_shape
from ._limits import PlannedTest, excitation_limits
from ._linear import ReducedEhsa, full_order_closed_loop
from ._params import EhsaParameters
from ._sim import simulate_ehsa

__all__ = ["CHANNELS", "BenchRun", "EhsaTruth", "digitize", "run"]

#: Channels of the rig file: name → (role, SI unit after calibration), read-only.
CHANNELS: Mapping[str, tuple[str, str]] = MappingProxyType({
    "yr_cmd": ("r", "m"),
    "y_pos": ("y", "m"),
    "p_supply": ("side", "Pa"),
    "p_return": ("side", "Pa"),
    "t_oil": ("side", "°C"),
})

# Side-channel realism [A]: 0.1 % of a 35 MPa transducer as white noise, a
# 9-piston pump at 1500 rpm (225 Hz ripple of 0.1 MPa), oil warming 0.5 °C/min.
_P_NOISE = 35e3  # [Pa] std, white at the analog rate
_RIPPLE = (0.1e6, 225.0)  # [Pa], [Hz]
_T_NOISE = 0.02  # [°C] std
_T_DRIFT = 0.5 / 60.0  # [°C/s]

#: Longest analog record a run simulates [samples at oversample·f_acq]: the chain holds
#: about 14 doubles per analog sample (actuator, transducers, noise, filter outputs), so
#: this is about 3.5 GiB of working memory.
_MAX_ANALOG_SAMPLES = 2**25

# Anti-alias filter at the analog rate: sections (first-order hold, many channels at
# once) or a discrete state space (zero-order hold, one channel).
_Filter = NDArray[np.float64] | StateSpace


@dataclass(frozen=True)
class EhsaTruth:
    """What the identification should find, and how it was made.

    Parameters
    ----------
    params : EhsaParameters
        The actuator's physical parameters.
    fidelity : {"reduced", "full", "nonlinear"}
        The model that produced the data.
    c : float
        Reference gain ``K_TM·K_driver`` [m/m].
    F : float
        Feedback gain ``K_fb`` [m/m].
    K : float
        Velocity gain of the reduced plant ``K_s2·K_qs/A_p`` [1/s].
    omega_hp : float
        Hydraulic natural frequency [rad/s].
    delta_hp : float
        Hydraulic damping ratio [-].
    """

    params: EhsaParameters
    fidelity: Fidelity
    c: float
    F: float
    K: float
    omega_hp: float
    delta_hp: float

    @property
    def exact(self) -> bool:
        """True if K, ω_hp, δ_hp are exact (the "reduced" fidelity)."""
        return self.fidelity == "reduced"

    def closed_loop(self) -> TransferFunction:
        """Return the reduced closed loop, the identification's model.

        ``cK/(s³/ω² + 2δs²/ω + s + FK)``.

        Returns
        -------
        TransferFunction
            Continuous, y_r [m] → y [m]: the identification's structure.
        """
        return ReducedEhsa(self.K, self.omega_hp, self.delta_hp).closed_loop(self.c, self.F)

    def to_dict(self) -> dict[str, Any]:
        """Return plain data: the truth and all physical parameters."""
        return {
            "fidelity": self.fidelity,
            "exact": self.exact,
            "K": self.K,
            "omega_hp": self.omega_hp,
            "delta_hp": self.delta_hp,
            "c": self.c,
            "F": self.F,
            "units": {"K": "1/s", "omega_hp": "rad/s", "delta_hp": "-", "c": "m/m", "F": "m/m"},
            "parameters": {k: float(v) for k, v in vars(self.params).items()},
        }


@dataclass(frozen=True, eq=False)
class BenchRun:
    """One run of the virtual rig: the raw record and the truth.

    Parameters
    ----------
    bench : EhsaBench
        The rig.
    excitation : Excitation
        The excitation played, designed at ``bench.f_s`` [m].
    truth : EhsaTruth
        The truth.
    raw : Experiment
        The rig file's content: volts at ``f_acq``, channels
        :data:`CHANNELS` (``yr_cmd`` role r, ``y_pos`` role y, side
        channels ``p_supply``, ``p_return``, ``t_oil``).
    clean : Experiment
        The same channels without any noise and without quantisation [V].
    command : ndarray
        Position command applied, after the DAC, at ``f_acq`` [m].
    position : ndarray
        Actuator position at the ADC's sampling instants, before the
        transducer (no filter, no noise) [m].
    signal_rms : float
        ``rms(y − ȳ)`` of the clean position at ``f_s`` [m].
    noise_std : float
        Standard deviation of the position noise at ``f_s`` (sensor plus
        quantisation) the budget aims at [m].
    sensor_noise_std : float
        Standard deviation of the white sensor noise at the analog rate [m].
    quantisation_std : float
        Quantisation's share of `noise_std` [m].
    seed : int or None
        The integer seed, if the run was seeded with one.
    warnings : tuple of str
        The warnings the run issued (clipping, spool saturation, ...).
    """

    bench: EhsaBench
    excitation: Excitation
    truth: EhsaTruth
    raw: Experiment
    clean: Experiment
    command: NDArray[np.float64]
    position: NDArray[np.float64]
    signal_rms: float
    noise_std: float
    sensor_noise_std: float
    quantisation_std: float
    seed: int | None = None
    warnings: tuple[str, ...] = field(default=())

    @property
    def n_samples(self) -> int:
        """Record length at the identification rate ``f_s``."""
        return self.excitation.n_samples

    @property
    def snr_db(self) -> float:
        """Design signal-to-noise ratio at ``f_s`` [dB] (inf: no noise)."""
        if self.noise_std == 0.0:
            return math.inf
        return 20.0 * math.log10(self.signal_rms / self.noise_std)

    def calibration(self) -> dict[str, float]:
        """Return the calibration gain volts → SI per channel."""
        b = self.bench
        assert b.position_sensitivity and b.command_sensitivity  # resolved
        assert b.p_supply_sensitivity and b.p_return_sensitivity
        return {
            "yr_cmd": 1.0 / b.command_sensitivity,
            "y_pos": 1.0 / b.position_sensitivity,
            "p_supply": 1.0 / b.p_supply_sensitivity,
            "p_return": 1.0 / b.p_return_sensitivity,
            "t_oil": 1.0 / b.temperature_sensitivity,
        }


def run(
    bench: EhsaBench,
    excitation: Excitation,
    *,
    rng: np.random.Generator | int,
) -> BenchRun:
    """Play an excitation on the rig and record what the DAQ writes.

    Parameters
    ----------
    bench : EhsaBench
        The rig.
    excitation : Excitation
        Commanded position [m], designed at ``bench.f_s`` (``dt =
        1/f_s``), e.g. ``prbs(11, clock=10, amplitude=1e-3, dt=1e-3)``;
        its peak must lie within the command range and the stroke.
    rng : numpy.random.Generator or int
        Source of the noise, or a seed (recorded in the result).

    Returns
    -------
    BenchRun
        The raw record in volts at ``f_acq``, its clean counterpart and
        the truth.

    Raises
    ------
    DataError
        The excitation is not sampled at ``f_s``, its peak exceeds the
        stroke, the command range or the DAC range, or at the analog rate
        it is longer than 2**25 samples (3.5 GiB of working memory).

    Warns
    -----
    ServoidWarning
        Before the simulation: `f_s` cannot resolve the actuator's
        hydraulic resonance (:meth:`EhsaBench.resolution_note`); the
        test asks more than the actuator can do (load pressure beyond
        :data:`~servoid.plants.ehsa.PRESSURE_FRACTION` of the supply, spool
        travel or rate, flapper travel, velocity, stroke:
        :func:`~servoid.plants.ehsa.excitation_limits`).  After it: a
        channel clipped at the ADC range; the converter's quantisation
        alone exceeds the noise the SNR allows.

    Examples
    --------
    >>> from servoid.signals import prbs
    >>> ex = prbs(7, clock=10, amplitude=1e-3, dt=1e-3)
    >>> rec = run(EhsaBench(), ex, rng=1)
    >>> rec.raw.n_samples, rec.raw.names[:2]
    (6350, ('yr_cmd', 'y_pos'))
    """
    if not isinstance(bench, EhsaBench):
        raise OptionTypeError(f"bench must be an EhsaBench, got {type(bench).__name__}")
    _check_excitation(bench, excitation)
    gen, seed = resolve_rng(rng, "run")
    notes: list[str] = []
    unresolved = bench.resolution_note()
    if unresolved:  # before the simulation, which is long at the rates that resolve it
        note_warning(notes, unresolved)
    saturates = planned_test(bench, excitation).note()
    if saturates:  # where a real actuator would saturate, before the simulation
        model = ("shows it" if bench.fidelity == "nonlinear" else
                 f"does not show it: the {bench.fidelity!r} model stays linear")
        note_warning(notes, f"{saturates}; the bench {model}")
    return _run(bench, excitation, gen, seed, notes)


def planned_test(bench: EhsaBench, excitation: Excitation) -> PlannedTest:
    """Return what `excitation` asks of the bench's actuator (:func:`excitation_limits`)."""
    return excitation_limits(bench.params, excitation)


def digitize(
    bench: EhsaBench,
    volts: NDArray[np.float64],
    *,
    hold: Hold = "foh",
) -> NDArray[np.float64]:
    """Anti-alias filter, sample and quantise an analog signal.

    Parameters
    ----------
    bench : EhsaBench
        The rig (filter, rates, converter).
    volts : ndarray, shape (N,)
        The analog signal [V] sampled at ``oversample·f_acq``, N a
        multiple of ``oversample``.
    hold : {"foh", "zoh"}
        How the signal runs between samples: linearly (a smooth signal)
        or as a staircase (a DAC output).

    Returns
    -------
    ndarray, shape (N/oversample,)
        The ADC's readings [V] at ``f_acq``, multiples of ``bench.lsb``.

    Warns
    -----
    ServoidWarning
        Samples clipped at ±``adc_range``.
    """
    if not isinstance(bench, EhsaBench):
        raise OptionTypeError(f"bench must be an EhsaBench, got {type(bench).__name__}")
    check_option("hold", hold, ("foh", "zoh"))
    x = np.asarray(volts, dtype=np.float64)
    if x.ndim != 1 or x.size < bench.oversample or x.size % bench.oversample:
        raise DataError(f"volts must be 1-D with a length that is a multiple of oversample = "
                        f"{bench.oversample}, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise DataError("volts must be finite")
    sos = _anti_alias(bench)[hold]
    out, clipped = quantise(_sample(sos, x, bench.oversample), bench.bits, bench.lsb)
    if clipped:
        note_warning([], _clip_message("signal", clipped, out.size, bench))
    return out


# -- the chain ---------------------------------------------------------------


def _run(bench: EhsaBench, ex: Excitation, gen: np.random.Generator,
         seed: int | None, notes: list[str]) -> BenchRun:
    q, m = bench.decimation, bench.oversample
    p = bench.params
    s_cmd, s_pos = bench.command_sensitivity, bench.position_sensitivity
    assert s_cmd is not None and s_pos is not None  # resolved by EhsaBench
    dt_an = bench.dt_acq / m
    v_cmd, _ = quantise(np.repeat(ex.values, q) * s_cmd, bench.bits, bench.lsb)
    command = v_cmd / s_cmd
    y_an = _actuator(bench, np.repeat(command, m), dt_an)
    n_an = y_an.size
    filt = _anti_alias(bench)

    t_an = np.arange(n_an) * dt_an
    amp, f_rip = _RIPPLE
    sens = _side_sensitivities(bench)
    analog = np.column_stack([
        y_an * s_pos,
        (p.P_s + amp * np.sin(2 * np.pi * f_rip * t_an)) * sens["p_supply"],
        np.full(n_an, p.P_T * sens["p_return"]),
        (bench.oil_temperature + _T_DRIFT * t_an) * sens["t_oil"],
    ])
    pos_clean, *side = _sample(filt["foh"], analog, m).T
    side_clean = dict(zip(("p_supply", "p_return", "t_oil"), side, strict=True))
    del analog
    if bench.reference == "command":  # the codes written to the DAC: a staircase
        cmd_clean = v_cmd.copy()
    else:  # read back through the anti-alias filter and the ADC
        cmd_clean = _sample(filt["zoh"], np.repeat(v_cmd, m), m)
    signal_rms = _rms_at_fs(bench, pos_clean / s_pos)
    g_s = _noise_gain(bench, filt["foh"], m)
    g_q = _noise_gain(bench, None, 1)
    quant_std = bench.lsb / math.sqrt(12.0) / s_pos * g_q
    sensor_std, noise_std = 0.0, quant_std
    if bench.snr_db is not None:
        noise_std = signal_rms / 10.0 ** (bench.snr_db / 20.0)
        if noise_std > quant_std:
            sensor_std = math.sqrt(noise_std**2 - quant_std**2) / g_s
        else:
            note_warning(notes,
                f"quantisation alone ({quant_std * 1e6:.3g} µm rms at f_s with {bench.bits} "
                f"bits) exceeds the noise of SNR {bench.snr_db:g} dB "
                f"({noise_std * 1e6:.3g} µm); the data are noisier than asked: use more bits "
                "or a larger amplitude")
            noise_std = quant_std
    # Draw every noise sequence whatever its size, in a fixed order, so one seed
    # gives the same realisation (scaled) at any SNR.
    white = gen.standard_normal((n_an, 4))
    white *= [sensor_std * s_pos, _P_NOISE * sens["p_supply"], _P_NOISE * sens["p_return"],
              _T_NOISE * sens["t_oil"]]
    pos_noise, *side_noise = _sample(filt["foh"], white, m).T
    del white
    clean_values = {"yr_cmd": cmd_clean, "y_pos": pos_clean, **side_clean}
    noisy_values = {"yr_cmd": cmd_clean, "y_pos": pos_clean + pos_noise,
                    **{k: v + w for (k, v), w in zip(side_clean.items(), side_noise,
                                                     strict=True)}}
    raw_values = {}
    for name, values in noisy_values.items():
        raw_values[name], clipped = quantise(values, bench.bits, bench.lsb)
        if clipped:
            note_warning(notes, _clip_message(name, clipped, values.size, bench))

    truth = EhsaTruth(params=p, fidelity=bench.fidelity, c=bench.c, F=bench.F, K=p.K,
                      omega_hp=p.omega_hp, delta_hp=p.delta_hp)
    meta = {"source": "servoid.bench", "fidelity": bench.fidelity, "f_s": bench.f_s,
             "reference": bench.reference,
             "bits": bench.bits, "snr_db": "none" if bench.snr_db is None else bench.snr_db,
             "seed": "none" if seed is None else seed, "excitation": ex.kind}
    return BenchRun(
        bench=bench,
        excitation=ex,
        truth=truth,
        raw=_experiment(raw_values, bench, meta),
        clean=_experiment(clean_values, bench, meta),
        command=command,
        position=y_an[::m].copy(),
        signal_rms=signal_rms,
        noise_std=noise_std,
        sensor_noise_std=sensor_std,
        quantisation_std=quant_std,
        seed=seed,
        warnings=tuple(notes),
    )


def _actuator(bench: EhsaBench, y_r: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
    p = bench.params
    if bench.fidelity == "nonlinear":
        return simulate_ehsa(p, y_r, dt).y
    if bench.fidelity == "reduced":
        loop = ReducedEhsa.from_parameters(p).closed_loop(bench.c, bench.F)
    else:
        loop = full_order_closed_loop(p)
    return discretise(realise(loop), dt, "zoh").simulate(y_r)


def _anti_alias(bench: EhsaBench) -> dict[str, _Filter]:
    ss = realise(bench.anti_alias())
    dt = bench.dt_acq / bench.oversample
    return {"zoh": discretise(ss, dt, "zoh"), "foh": discrete_sos(ss, dt)}


def _sample(filt: _Filter, x: NDArray[np.float64], m: int) -> NDArray[np.float64]:
    """Filter from rest and keep every m-th sample (the ADC).

    Sections filter every column of `x`; a state space filters one signal.
    """
    if isinstance(filt, StateSpace):
        return np.asarray(filt.simulate(x)[::m], dtype=np.float64)
    return np.asarray(sps.sosfilt(filt, x, axis=0)[::m], dtype=np.float64)


def _side_sensitivities(bench: EhsaBench) -> dict[str, float]:
    assert bench.p_supply_sensitivity is not None and bench.p_return_sensitivity is not None
    return {"p_supply": bench.p_supply_sensitivity, "p_return": bench.p_return_sensitivity,
            "t_oil": bench.temperature_sensitivity}


def _rms_at_fs(bench: EhsaBench, x: NDArray[np.float64]) -> float:
    exp = Experiment((Channel("x", "y", x),), bench.dt_acq)
    xs = decimate(exp, bench.decimation)["x"] if bench.decimation > 1 else x
    return float(np.sqrt(np.mean((xs - xs.mean()) ** 2)))


def _noise_gain(bench: EhsaBench, sos: _Filter | None, m: int) -> float:
    """Gain of filter → sample every m → decimate for white noise, exact.

    The chain is periodically time-varying with period ``m·q`` input
    samples; the output variance per unit input variance is the sum of
    squares of one output sample's weights, which equals the summed
    squared responses to ``m·q`` impulses at consecutive positions.
    """
    q = bench.decimation
    n, _ = noise_gain_shape(bench.f_acq, q, m)  # bounded by EhsaBench
    x = np.zeros((n, m * q))
    x[n // 2 + np.arange(m * q), np.arange(m * q)] = 1.0
    y = _sample(sos, x, m) if sos is not None else x[::m]
    channels = [Channel(f"x{j}", "side", y[:, j]) for j in range(m * q)]
    exp = Experiment(tuple(channels), bench.dt_acq)
    if q > 1:
        exp = decimate(exp, q)
    return math.sqrt(sum(float(np.sum(ch.values**2)) for ch in exp.channels))


def _experiment(values: dict[str, NDArray[np.float64]], bench: EhsaBench,
                notes: dict[str, Any]) -> Experiment:
    channels = tuple(Channel(name, CHANNELS[name][0], values[name], "V")  # type: ignore[arg-type]
                     for name in CHANNELS)
    return Experiment(channels, bench.dt_acq, name="ehsa_bench", notes=notes)


def _check_excitation(bench: EhsaBench, ex: object) -> None:
    if not isinstance(ex, Excitation):
        raise OptionTypeError(f"excitation must be a servoid.signals.Excitation, got "
                              f"{type(ex).__name__}")
    if not math.isclose(ex.dt, bench.dt, rel_tol=1e-9):
        raise DataError(
            f"excitation.dt = {ex.dt:g} s must be the identification period 1/f_s = "
            f"{bench.dt:g} s: design the excitation at f_s (e.g. prbs(11, clock=10, "
            f"dt={bench.dt:g})); the DAQ plays it at f_acq = {bench.f_acq:g} Hz by "
            "zero-order hold"
        )
    if ex.clock is not None and ex.clock < 1:
        raise DataError(f"the excitation clock must be >= 1 sample per bit, got {ex.clock}")
    n_analog = ex.n_samples * bench.decimation * bench.oversample
    if n_analog > _MAX_ANALOG_SAMPLES:
        raise DataError(
            f"the excitation of {ex.n_samples:,} samples at f_s = {bench.f_s:g} Hz is "
            f"simulated at oversample·f_acq = {bench.oversample * bench.f_acq:g} Hz: "
            f"{n_analog:,} analog samples, over the budget of {_MAX_ANALOG_SAMPLES:,} (about "
            f"{14 * 8 * _MAX_ANALOG_SAMPLES / 2**30:.2g} GiB of working memory); shorten the "
            "excitation (a shorter register, fewer periods or fewer samples per bit) or lower f_acq"
        )
    peak = float(np.max(np.abs(ex.values)))
    p = bench.params
    assert bench.command_sensitivity is not None
    if peak > p.stroke:
        raise DataError(
            f"excitation peak {peak * 1e3:.4g} mm exceeds the stroke ±{p.stroke * 1e3:.4g} mm; "
            "lower the amplitude (or the offset)")
    if peak > bench.command_range:
        raise DataError(
            f"excitation peak {peak * 1e3:.4g} mm exceeds the command range "
            f"±{bench.command_range * 1e3:.4g} mm; lower the amplitude (or the offset)")
    if peak * bench.command_sensitivity > bench.adc_range:
        raise DataError(
            f"excitation peak {peak * 1e3:.4g} mm is {peak * bench.command_sensitivity:.4g} V, "
            f"beyond the DAC range ±{bench.adc_range:g} V; lower the amplitude or the "
            "command sensitivity")


def _clip_message(name: str, clipped: int, n: int, bench: EhsaBench) -> str:
    return (f"channel {name!r} clipped at ±{bench.adc_range:g} V on {clipped} of {n} samples; "
            "lower the amplitude or the transducer sensitivity")
