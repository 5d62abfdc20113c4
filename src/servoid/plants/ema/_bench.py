"""The EMA's virtual test rig: the drive, the actuator, the sensors, the logger.

The rig's logger is clocked by the drive and records once per drive
sample ``dt = 1/f_ctrl``, as a drive's scope does:

* ``x_ref`` [counts]: the position reference the drive reads (integer
  counts of ``reference_lsb``; the drive runs on exactly these values);
* ``u_cmd`` [counts]: the voltage command, the drive's ``voltage_bits``
  word over ±``u_max`` (what the power stage holds until the next sample);
* ``theta_m`` [counts]: the motor encoder, ``encoder_counts`` per
  revolution, as the drive reads it;
* ``i_motor`` [V]: the current sensor (±``current_range`` on
  ±``adc_range``), and ``x_load`` [V]: the LVDT on the load
  (±``position_range``), both through the logger's analog anti-alias
  filter (Butterworth, order ``aa_order``, ``aa_cutoff``) and its
  ``bits``-bit ADC.

The actuator is simulated ``oversample`` times faster than the drive
(:func:`~servoid.plants.ema.simulate_ema`, RK4 with the drive's voltage
held), so the anti-alias filter acts on the analog signal (first-order
hold between integration steps) the way the real one does.  The two
analog sensors carry white noise at that analog rate
(``current_noise``, ``position_noise``, their standard deviations there),
which the drive reads unfiltered at its samples and the logger through
the filter.  The experiment file decimates nothing: the identification
reduces its own rows after its filters (``[identify] row_step``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._checks import as_array, as_float, as_instance, as_int
from ..._errors import DataError, ModelError, OptionTypeError
from ..._lazy import signal as sps
from ._control import TVC_CONTROLLER, EmaController
from ._params import TVC_EMA, EmaParameters
from ._sim import EmaResponse, simulate_ema

__all__ = ["CHANNELS", "EmaBench", "EmaRun", "bench_reference", "run_bench", "truth_parameters"]

#: Channels of the rig file: name → (role, unit after calibration).
CHANNELS: dict[str, tuple[str, str]] = {
    "x_ref": ("r", "m"),
    "u_cmd": ("u", "V"),
    "i_motor": ("side", "A"),
    "theta_m": ("side", "rad"),
    "x_load": ("y", "m"),
}
#: Longest simulated record [integration steps]: five states and the noise per step.
_MAX_ANALOG = 2**24


@dataclass(frozen=True)
class EmaBench:
    """The rig: actuator, drive, sensors and logger.

    Parameters
    ----------
    params : EmaParameters
        The actuator.
    controller : EmaController
        The drive's loops.
    f_ctrl : float
        Drive and logger rate [Hz].  10 kHz.
    oversample : int
        Integration steps per drive sample (the analog rate).  10.
    aa_order : int
        Order of the logger's Butterworth anti-alias filter.  4.
    aa_cutoff : float or None
        Its cutoff [Hz]; None: 0.2·f_ctrl.
    bits : int
        ADC resolution, 8..24.  16.
    adc_range : float
        ADC range ±[V].  10.
    current_range : float
        Current at full scale of the current sensor ±[A].  50.
    position_range : float
        Load position at full scale of the LVDT ±[m].  0.05.
    current_noise : float
        Current sensor noise, std at the analog rate [A].  0.1.
    position_noise : float
        LVDT noise, std at the analog rate [m].  4e-6.
    voltage_bits : int
        Bits of the drive's voltage word over ±u_max.  16.
    reference_lsb : float
        One count of the position reference [m].  1e-7.
    f_ext : float
        Constant external force on the load [N], positive against
        positive motion.  0.
    """

    params: EmaParameters = TVC_EMA
    controller: EmaController = TVC_CONTROLLER
    f_ctrl: float = 10_000.0
    oversample: int = 10
    aa_order: int = 4
    aa_cutoff: float | None = None
    bits: int = 16
    adc_range: float = 10.0
    current_range: float = 50.0
    position_range: float = 0.05
    current_noise: float = 0.1
    position_noise: float = 4e-6
    voltage_bits: int = 16
    reference_lsb: float = 1e-7
    f_ext: float = 0.0

    def __post_init__(self) -> None:
        as_instance("params", self.params, EmaParameters, "EmaParameters")
        as_instance("controller", self.controller, EmaController, "an EmaController")
        for name in ("f_ctrl", "adc_range", "current_range", "position_range",
                     "reference_lsb"):
            object.__setattr__(self, name, as_float(name, getattr(self, name), positive=True))
        for name in ("current_noise", "position_noise"):
            object.__setattr__(self, name, as_float(name, getattr(self, name), nonneg=True))
        object.__setattr__(self, "f_ext", as_float("f_ext", self.f_ext, unit="N"))
        for name, lo, hi in (("oversample", 1, 1000), ("aa_order", 1, 12), ("bits", 8, 24),
                             ("voltage_bits", 8, 32)):
            object.__setattr__(self, name, as_int(name, getattr(self, name), minimum=lo,
                                                  maximum=hi))
        cutoff = 0.2 * self.f_ctrl if self.aa_cutoff is None else as_float(
            "aa_cutoff", self.aa_cutoff, positive=True, unit="Hz")
        if cutoff >= 0.5 * self.f_ctrl:
            raise DataError(f"aa_cutoff = {cutoff:g} Hz must lie below the Nyquist frequency "
                            f"{0.5 * self.f_ctrl:g} Hz of the logger")
        object.__setattr__(self, "aa_cutoff", float(cutoff))
        if not math.isfinite(self.controller.u_max):
            raise ModelError("the bench logs the voltage command as a word over ±u_max: give "
                             "the controller a finite u_max")

    @property
    def dt(self) -> float:
        """Drive and logger period [s]."""
        return 1.0 / self.f_ctrl

    @property
    def lsb(self) -> float:
        """One ADC code [V]."""
        return 2.0 * self.adc_range / 2**self.bits

    @property
    def current_sensitivity(self) -> float:
        """Current sensor [V/A]."""
        return self.adc_range / self.current_range

    @property
    def position_sensitivity(self) -> float:
        """LVDT [V/m]."""
        return self.adc_range / self.position_range

    @property
    def voltage_lsb(self) -> float:
        """One count of the voltage command [V]."""
        return self.controller.u_max / 2 ** (self.voltage_bits - 1)

    @property
    def angle_lsb(self) -> float:
        """One encoder count [rad] (0 for an exact encoder)."""
        cpr = self.controller.encoder_counts
        return 2.0 * math.pi / cpr if cpr else 0.0

    def calibration(self) -> dict[str, float]:
        """Gain of each logged channel, raw → SI."""
        return {"x_ref": self.reference_lsb, "u_cmd": self.voltage_lsb,
                "i_motor": 1.0 / self.current_sensitivity,
                "theta_m": self.angle_lsb if self.angle_lsb else 1.0,
                "x_load": 1.0 / self.position_sensitivity}

    def with_(self, **changes: Any) -> EmaBench:
        """Return a copy with some settings changed."""
        return replace(self, **changes)


@dataclass(frozen=True, eq=False)
class EmaRun:
    """One run of the rig: its raw record and its simulation.

    Attributes
    ----------
    bench : EmaBench
        The rig.
    raw : Experiment
        The rig file's content: counts and volts per drive sample
        (:data:`CHANNELS`).
    response : EmaResponse
        The simulation (true states per drive sample).
    reference : ndarray
        The reference the drive ran on [m] (whole counts).
    seed : int or None
        The integer seed, if seeded with one.
    warnings : tuple of str
        Clipping and limits met.
    """

    bench: EmaBench
    raw: Any
    response: EmaResponse
    reference: NDArray[np.float64]
    seed: int | None = None
    warnings: tuple[str, ...] = field(default=())

    def truth(self) -> dict[str, float]:
        """The identification's parameters as the simulation had them."""
        return truth_parameters(self.bench.params, self.bench.f_ext)


def truth_parameters(p: EmaParameters, f_ext: float = 0.0) -> dict[str, float]:
    """The parameters that fit_ema reports, from a parameter set.

    Parameters
    ----------
    p : EmaParameters
        The actuator.
    f_ext : float
        The constant external force [N].
    """
    as_instance("p", p, EmaParameters, "EmaParameters")
    f_ext = as_float("f_ext", f_ext, unit="N")
    n2 = p.transmission**2
    return {"K_m": p.K_m, "R": p.R, "L": p.L, "J_total": p.J_m + p.m_L / n2, "J_m": p.J_m,
            "m_L": p.m_L, "k_s": p.k_s, "c_s": p.c_s, "b_total": p.b_m + p.b_L / n2,
            "b_m": p.b_m, "b_L": p.b_L, "T_c_total": p.T_cm + p.F_cL / p.transmission,
            "T_cm": p.T_cm, "F_cL": p.F_cL, "F_0": float(f_ext)}


def bench_reference(
    bench: EmaBench,
    *,
    duration: float = 8.0,
    sweep: float = 0.02,
    sweep_hz: float = 0.25,
    amplitude: float = 2e-3,
    f_min: float = 1.0,
    f_max: float = 40.0,
    lines: int = 30,
) -> NDArray[np.float64]:
    """The rig's test: a slow sweep with a multisine on top [m].

    ``sweep·sin(2π·sweep_hz·t)`` over most of the stroke, plus a random-phase
    multisine of about ``lines`` log-spaced lines in ``[f_min, f_max]``
    whose amplitudes fall as 1/f (equal velocity per line), scaled to the
    peak ``amplitude``.  The sweep keeps the motion one-way between its
    turning points (Coulomb friction is then a clean ± constant), the
    multisine excites the dynamics.  The phases are fixed (seed 0): the
    test is the same for every unit.

    Parameters
    ----------
    bench : EmaBench
        The rig (its rate and stroke).
    duration : float
        Length [s].
    sweep : float
        Amplitude of the slow sweep [m].
    sweep_hz : float
        Its frequency [Hz].
    amplitude : float
        Peak of the multisine [m].
    f_min, f_max : float
        Band of the multisine [Hz].
    lines : int
        About how many lines.

    Returns
    -------
    ndarray
        The reference per drive sample [m], starting at 0.
    """
    as_instance("bench", bench, EmaBench, "an EmaBench")
    duration = as_float("duration", duration, positive=True, unit="s")
    for name, value in (("sweep", sweep), ("amplitude", amplitude)):
        as_float(name, value, nonneg=True, unit="m")
    sweep_hz = as_float("sweep_hz", sweep_hz, positive=True, unit="Hz")
    f_min = as_float("f_min", f_min, positive=True, unit="Hz")
    f_max = as_float("f_max", f_max, positive=True, unit="Hz")
    lines = as_int("lines", lines, minimum=1)
    n = round(duration * bench.f_ctrl)
    if not f_min < f_max < 0.25 * bench.f_ctrl:
        raise DataError(f"need f_min < f_max < f_ctrl/4, got {f_min:g} and {f_max:g} Hz")
    if n * bench.oversample > _MAX_ANALOG:
        raise DataError(f"duration = {duration:g} s is {n * bench.oversample:,} integration "
                        f"steps, over the budget of {_MAX_ANALOG:,}; shorten the test")
    t = np.arange(n) / bench.f_ctrl
    f0 = 1.0 / duration
    ks = np.unique(np.round(np.geomspace(f_min, f_max, lines) / f0).astype(int))
    ks = ks[ks >= 1]
    phases = np.random.default_rng(0).uniform(0.0, 2.0 * np.pi, ks.size)
    ms = np.zeros(n)
    for k, ph in zip(ks, phases, strict=True):
        ms += np.sin(2.0 * np.pi * k * f0 * t + ph) / k
    ms -= ms[0]
    peak = float(np.max(np.abs(ms)))
    ms *= amplitude / peak if peak > 0 else 0.0
    ref = sweep * np.sin(2.0 * np.pi * sweep_hz * t) + ms
    return np.asarray(ref, dtype=np.float64)


def run_bench(bench: EmaBench, reference: ArrayLike, *, rng: np.random.Generator | int
              ) -> EmaRun:
    """Play a reference on the rig and record what the logger writes.

    Parameters
    ----------
    bench : EmaBench
        The rig.
    reference : array_like
        Position reference per drive sample [m] (e.g.
        :func:`bench_reference`), within ±stroke.
    rng : numpy.random.Generator or int
        Source of the sensor noise, or a seed (recorded).

    Returns
    -------
    EmaRun
        The raw record and the simulation.

    Raises
    ------
    DataError
        A reference beyond the stroke or the reference's counts, or too
        long for the simulation budget.

    Warns
    -----
    ServoidWarning
        A channel clipped at the ADC range; the drive at its current or
        voltage limit.
    """
    from ...bench import butterworth, discrete_sos, note_warning, quantise, realise, resolve_rng
    from ...data import Channel, Experiment

    if not isinstance(bench, EmaBench):
        raise OptionTypeError(f"bench must be an EmaBench, got {type(bench).__name__}")
    ref = as_array("reference", reference, ndim=1, min_size=16)
    gen, seed = resolve_rng(rng, "run_bench")
    p, m = bench.params, bench.oversample
    peak = float(np.max(np.abs(ref)))
    if peak > p.stroke:
        raise DataError(f"the reference reaches {peak * 1e3:.4g} mm, beyond the stroke "
                        f"±{p.stroke * 1e3:.4g} mm; lower its amplitude")
    if ref.size * m > _MAX_ANALOG:
        raise DataError(f"{ref.size:,} samples at oversample {m} are {ref.size * m:,} "
                        f"integration steps, over the budget of {_MAX_ANALOG:,}; shorten the "
                        "reference or lower oversample")
    ref_counts = np.rint(ref / bench.reference_lsb)
    ref_q = ref_counts * bench.reference_lsb
    notes: list[str] = []
    n_an = ref.size * m
    noise = gen.standard_normal((n_an, 2)) * [bench.current_noise, bench.position_noise]
    out = simulate_ema(p, ref_q, bench.dt, controller=bench.controller, f_ext=bench.f_ext,
                       dt_int=bench.dt / m, analog=True,
                       measurement_noise={"current": noise[::m, 0], "position": noise[::m, 1]})
    assert out.analog is not None
    sos = discrete_sos(realise(butterworth(bench.aa_order, bench.aa_cutoff)), bench.dt / m)
    analog = np.column_stack([(out.analog[:, 0] + noise[:, 0]) * bench.current_sensitivity,
                              (out.analog[:, 3] + noise[:, 1]) * bench.position_sensitivity])
    zi = sps.sosfilt_zi(sos)[:, :, None] * analog[0][None, None, :]
    sampled = np.asarray(sps.sosfilt(sos, analog, axis=0, zi=zi)[0][::m], dtype=np.float64)
    raw = {}
    for col, name in enumerate(("i_motor", "x_load")):
        raw[name], clipped = quantise(sampled[:, col], bench.bits, bench.lsb)
        if clipped:
            note_warning(notes, f"channel {name!r} clipped at ±{bench.adc_range:g} V on "
                         f"{clipped} of {ref.size} samples; raise its range", stacklevel=3)
    raw["x_ref"] = ref_counts
    raw["u_cmd"] = np.rint(out.voltage / bench.voltage_lsb)
    raw["theta_m"] = (np.rint(out.measured_angle / bench.angle_lsb) if bench.angle_lsb
                      else np.asarray(out.measured_angle))
    sat = out.saturation_fraction()
    for what, frac in sat.items():
        if frac > 0:
            note_warning(notes, f"the drive was at its {what} limit on {100 * frac:.2g} % of "
                         "the samples; the identification is unaffected (it uses the applied "
                         "voltage), but lower the amplitude for a linear test", stacklevel=3)
    units = {"x_ref": "count", "u_cmd": "count", "i_motor": "V", "theta_m": "count",
             "x_load": "V"}
    channels = tuple(Channel(name, CHANNELS[name][0], raw[name], units[name])  # type: ignore[arg-type]
                     for name in CHANNELS)
    meta = {"source": "servoid.plants.ema bench", "seed": "none" if seed is None else seed,
            "f_ctrl": bench.f_ctrl}
    exp = Experiment(channels, bench.dt, name="ema_bench", notes=meta)
    return EmaRun(bench, exp, out, ref_q, seed, tuple(notes))
