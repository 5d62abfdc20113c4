"""Write a bench run as a real rig would: rig file, experiment TOML, truth.

Three files in one folder, each written atomically, none overwritten
unless asked (all targets are checked before the first is written):

* ``<name>.tdms`` or ``<name>.csv``: the raw channels in volts at
  ``f_acq`` (TDMS with waveform properties and the run's notes as group
  properties; CSV with a time column);
* ``<name>.toml``: the experiment file that maps the channels with their
  calibration volts → SI, decimates to ``f_s`` (anti-aliased, zero
  phase), removes the mean, splits in halves of whole periods, declares
  the rig (``[rig]``: the anti-alias filter and whether the reference is
  the DAC command or read back), states the loop gains and asks for the
  one-step closed-loop identification with the discretisation chosen
  from that declaration (``"auto"``: exact for either reference, and
  defined for any resonance, unlike a prewarped Tustin map, which fails
  for ω_hp beyond π·f_s);
* ``truth.json``: the true parameters and how the data were made.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Literal

from ..._atomic import atomic_path, check_writable
from ..._checks import as_bool, as_instance, as_path, as_str
from ..._errors import OptionTypeError, check_option
from ...data import RigFormat, write_experiment_spec
from ._bench import CHANNELS, BenchRun

__all__ = ["RigFormat", "write_bench", "write_bench_files"]

#: The formats the bench writes, its default first.
_FORMATS = RigFormat.writable(first="tdms")

#: What the experiment file asks the identification for ([S1] ARX(3, 4, 0) start).
IDENTIFY: dict[str, Any] = {
    "method": "closedloop", "approach": ["indirect", "one-step"], "na": 3, "nb": 4, "nk": 0,
    # The bench's loop is continuous: the exact sampled model for the declared reference
    # (a staircase command with the rig's filter and decimation, or a band-limited read-back).
    "discretization": "auto",
}


def write_bench_files(
    run: BenchRun,
    folder: str | os.PathLike[str],
    *,
    format: str | RigFormat = "tdms",
    overwrite: bool = False,
    name: str = "ehsa",
) -> list[Path]:
    """Write the rig file, its experiment TOML and ``truth.json``.

    Parameters
    ----------
    run : BenchRun
        The result of :func:`~servoid.plants.ehsa.run`.
    folder : path-like
        Output folder, created if missing.
    format : {"tdms", "csv"} or RigFormat
        Rig file format (one :data:`~servoid.data.RIG_FORMATS` writes).
    overwrite : bool
        Replace existing files; otherwise :class:`OutputExistsError`
        before anything is written.
    name : str
        Stem of the rig file and the TOML.

    Returns
    -------
    list of pathlib.Path
        ``[rig file, TOML, truth.json]``.

    Examples
    --------
    >>> import tempfile
    >>> from servoid.signals import prbs
    >>> from servoid.plants.ehsa import EhsaBench, run
    >>> rec = run(EhsaBench(), prbs(7, clock=10, amplitude=1e-3, dt=1e-3), rng=1)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     [p.name for p in write_bench_files(rec, tmp)]
    ['ehsa.tdms', 'ehsa.toml', 'truth.json']
    """
    if not isinstance(run, BenchRun):
        raise OptionTypeError(f"run must be a BenchRun, got {type(run).__name__}")
    if not isinstance(format, RigFormat):
        check_option("format", format, _FORMATS)
    fmt = RigFormat.named(format)
    if not isinstance(name, str) or not name or "/" in name or os.sep in name:
        raise OptionTypeError(f"name must be a plain file stem, got {name!r}")
    folder = as_path("folder", folder)
    as_bool("overwrite", overwrite)
    rig = folder / f"{name}{fmt.suffixes[0]}"
    toml = folder / f"{name}.toml"
    truth = folder / "truth.json"
    for target in (rig, toml, truth):
        check_writable(target, overwrite)
    folder.mkdir(parents=True, exist_ok=True)
    fmt.write(run.raw, rig, overwrite=overwrite)
    write_experiment_spec(experiment_document(run, rig.name), toml, overwrite=overwrite)
    text = json.dumps(truth_document(run), indent=2, ensure_ascii=False) + "\n"
    with atomic_path(truth, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return [rig, toml, truth]


def write_bench(
    folder: str | os.PathLike[str],
    *,
    set: Literal["B", "C"] = "B",
    seed: int = 0,
    format: str | RigFormat = "tdms",
    overwrite: bool = False,
) -> list[Path]:
    """Rehearse the default test on the virtual rig and write its files.

    The test ``servoid bench ehsa`` runs by default: a PRBS (register 11,
    10 samples per bit, ±1 mm) at 1 kHz on the reduced model of a
    parameter set, acquired at 5 kHz with 16 bits and 30 dB SNR; then
    :func:`write_bench_files`.

    Parameters
    ----------
    folder : path-like
        Output folder, created if missing.
    set : {"B", "C"}
        Parameter set (:data:`~servoid.plants.ehsa.PARAMETER_SETS`).
    seed : int
        Seed of the noise.
    format : {"tdms", "csv"} or RigFormat
        Rig file format.
    overwrite : bool
        Replace existing files.

    Returns
    -------
    list of pathlib.Path
        ``[rig file, TOML, truth.json]``.
    """
    from ...signals import prbs
    from ._bench import run
    from ._bench_config import EhsaBench
    from ._params import PARAMETER_SETS

    check_option("set", set, tuple(PARAMETER_SETS))
    bench = EhsaBench(params=PARAMETER_SETS[set])
    excitation = prbs(11, clock=10, amplitude=1e-3, dt=bench.dt)
    return write_bench_files(run(bench, excitation, rng=seed), folder, format=format,
                             overwrite=overwrite)


def experiment_document(run: BenchRun, file: str) -> dict[str, Any]:
    """Return the experiment TOML of a run as a dictionary.

    Parameters
    ----------
    run : BenchRun
        The run.
    file : str
        The rig file, relative to the TOML's folder (``.tdms`` or ``.csv``).

    Returns
    -------
    dict
        TOML-shaped, for :func:`servoid.data.write_experiment_spec`.
    """
    as_instance("run", run, BenchRun, "a BenchRun (from servoid.plants.ehsa.run)")
    data: dict[str, Any] = {"file": as_str("file", file)}
    fmt = RigFormat.find(file)
    if fmt is not None and fmt.time is not None:  # the time column its writer wrote
        data["time"] = fmt.time
    # 15 significant digits: 1/(10 V/35 MPa) prints as 3500000.0, not ...0005.
    gains = {ch: float(f"{g:.15g}") for ch, g in run.calibration().items()}
    channels = {
        ch: {"source": ch, "role": role, "gain": gains[ch], "offset": 0.0, "unit": unit}
        for ch, (role, unit) in CHANNELS.items()
    }
    split: dict[str, Any] = {"fraction": 0.5}
    period = run.excitation.period
    # split() needs two whole periods when given one; a single period is cut in halves.
    if period is not None and run.excitation.n_samples // period >= 2:
        split["period"] = period
    return {
        "data": data,
        "channels": channels,
        "preprocess": {"decimate": run.bench.decimation, "detrend": "mean"},
        "split": split,
        "rig": {"anti_alias": {"order": run.bench.aa_order, "cutoff": run.bench.aa_cutoff},
                "reference": run.bench.reference},
        "loop": {"c": run.truth.c, "F": run.truth.F},
        "identify": dict(IDENTIFY),
        "report": {"truth": "truth.json"},  # a rehearsal: compare with what the bench knows
    }


def truth_document(run: BenchRun) -> dict[str, Any]:
    """Return the content of ``truth.json`` for a run.

    Parameters
    ----------
    run : BenchRun
        The run.

    Returns
    -------
    dict
        JSON-ready: the truth, the SNR and seed, the rig and the design.
    """
    as_instance("run", run, BenchRun, "a BenchRun (from servoid.plants.ehsa.run)")
    b, ex = run.bench, run.excitation
    rig = {
        "f_acq": b.f_acq, "f_s": b.f_s, "decimation": b.decimation, "oversample": b.oversample,
        "reference": b.reference,
        "aa_order": b.aa_order, "aa_cutoff": b.aa_cutoff, "bits": b.bits,
        "adc_range": b.adc_range, "lsb": b.lsb,
        "position_sensitivity": b.position_sensitivity,
        "command_sensitivity": b.command_sensitivity, "command_range": b.command_range,
        "p_supply_sensitivity": b.p_supply_sensitivity,
        "p_return_sensitivity": b.p_return_sensitivity,
        "temperature_sensitivity": b.temperature_sensitivity,
        "oil_temperature": b.oil_temperature,
    }
    excitation = {
        "kind": ex.kind, "n_samples": ex.n_samples, "dt": ex.dt, "period": ex.period,
        "clock": ex.clock, "band_hz": list(ex.band), "amplitude": ex.amplitude,
        "offset": ex.offset,
        "description": {k: v for k, v in ex.description.items()
                        if isinstance(v, (str, int, float, bool)) or v is None},
    }
    return {
        **run.truth.to_dict(),
        "snr_db": b.snr_db,
        "seed": run.seed,
        "noise": {"signal_rms_m": run.signal_rms, "noise_std_m": run.noise_std,
                  "sensor_noise_std_m": run.sensor_noise_std,
                  "quantisation_std_m": run.quantisation_std},
        "rig": rig,
        "excitation": excitation,
        "warnings": list(run.warnings),
    }

