"""Write an EMA bench run as a rig would: rig file, experiment file, truth.

Three files in one folder, each written atomically, none overwritten
unless asked (every target is checked before the first is written):

* ``<name>.tdms`` or ``<name>.csv``: the logged channels in counts and
  volts (:data:`~servoid.plants.ema._bench.CHANNELS`);
* ``<name>.toml``: the experiment file: each channel's calibration to SI,
  ``[rig] anti_alias`` (the logger's filter on the current and the LVDT),
  the drive's gains and limits as ``[loop]``, a split in halves and
  ``[identify] method = "ema"`` with the transmission;
* ``truth.json``: the parameters the simulation used, in the names the
  identification reports, and how the record was made.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from ..._atomic import atomic_path, check_writable
from ..._checks import as_bool, as_int, as_path
from ..._errors import OptionTypeError, check_option
from ...data import RigFormat
from ._bench import CHANNELS, EmaBench, EmaRun, bench_reference, run_bench

__all__ = ["experiment_document", "truth_document", "write_bench", "write_run"]

#: The formats the bench writes, its default first.
_FORMATS = RigFormat.writable(first="tdms")


def write_bench(
    folder: str | os.PathLike[str],
    *,
    bench: EmaBench | None = None,
    seed: int = 0,
    duration: float = 8.0,
    amplitude: float = 2e-3,
    sweep: float = 0.02,
    f_max: float = 40.0,
    format: str | RigFormat = "tdms",
    name: str = "ema",
    overwrite: bool = False,
) -> list[Path]:
    """Run the rig's identification test and write its files.

    Parameters
    ----------
    folder : path-like
        Output folder (created).
    bench : EmaBench, optional
        The rig; default :class:`EmaBench` (the nominal TVC EMA).
    seed : int
        Seed of the sensor noise.
    duration, amplitude, sweep, f_max : float
        The test (:func:`~servoid.plants.ema.bench_reference`): length
        [s], multisine peak [m], slow sweep amplitude [m], highest line [Hz].
    format : {"tdms", "csv"} or RigFormat
        Rig file format (one :data:`~servoid.data.RIG_FORMATS` writes).
    name : str
        Stem of the rig file and the experiment file.
    overwrite : bool
        Replace files of an earlier run.

    Returns
    -------
    list of pathlib.Path
        ``[rig file, experiment file, truth.json]``.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     [p.name for p in write_bench(tmp, duration=1.0)]
    ['ema.tdms', 'ema.toml', 'truth.json']
    """
    bench = EmaBench() if bench is None else bench
    seed = as_int("seed", seed, minimum=0)
    _check_targets(folder, name, _format(format), overwrite)
    reference = bench_reference(bench, duration=duration, amplitude=amplitude, sweep=sweep,
                                f_max=f_max)
    run = run_bench(bench, reference, rng=seed)
    return write_run(run, folder, format=format, name=name, overwrite=overwrite)


def write_run(run: EmaRun, folder: str | os.PathLike[str], *, format: str | RigFormat = "tdms",
              name: str = "ema", overwrite: bool = False) -> list[Path]:
    """Write a bench run's rig file, experiment file and truth.

    Parameters
    ----------
    run : EmaRun
        What :func:`~servoid.plants.ema.run_bench` returned.
    folder : path-like
        Output folder (created).
    format : {"tdms", "csv"} or RigFormat
        Rig file format.
    name : str
        Stem of the rig file and the experiment file.
    overwrite : bool
        Replace existing files; otherwise nothing is written.

    Returns
    -------
    list of pathlib.Path
        ``[rig file, experiment file, truth.json]``.
    """
    from ...data import write_experiment_spec

    if not isinstance(run, EmaRun):
        raise OptionTypeError(f"run must be an EmaRun, got {type(run).__name__}")
    fmt = _format(format)
    rig, toml, truth = _check_targets(folder, name, fmt, overwrite)
    rig.parent.mkdir(parents=True, exist_ok=True)
    fmt.write(run.raw, rig, overwrite=overwrite)
    write_experiment_spec(experiment_document(run, rig.name), toml, overwrite=overwrite)
    text = json.dumps(truth_document(run), indent=2, ensure_ascii=False) + "\n"
    with atomic_path(truth, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return [rig, toml, truth]


def experiment_document(run: EmaRun, file: str) -> dict[str, Any]:
    """The experiment file of a run, as a TOML-shaped dictionary.

    Parameters
    ----------
    run : EmaRun
        The run.
    file : str
        The rig file, relative to the experiment file.

    Returns
    -------
    dict
        For :func:`servoid.data.write_experiment_spec`.
    """
    b = run.bench
    data: dict[str, Any] = {"file": file}
    fmt = RigFormat.find(file)
    if fmt is not None and fmt.time is not None:  # the time column its writer wrote
        data["time"] = fmt.time
    gains = {ch: float(f"{g:.15g}") for ch, g in b.calibration().items()}
    channels = {ch: {"source": ch, "role": role, "gain": gains[ch], "offset": 0.0, "unit": unit}
                for ch, (role, unit) in CHANNELS.items()}
    return {
        "data": data,
        "channels": channels,
        "split": {"fraction": 0.5},
        "rig": {"anti_alias": {"order": b.aa_order, "cutoff": b.aa_cutoff},
                "reference": "command"},
        "loop": b.controller.to_dict(),
        "identify": {"method": "ema", "gear_ratio": b.params.N, "lead": b.params.lead},
        "report": {"truth": "truth.json"},
    }


def truth_document(run: EmaRun) -> dict[str, Any]:
    """The content of ``truth.json`` for a run.

    Parameters
    ----------
    run : EmaRun
        The run.

    Returns
    -------
    dict
        The identification's parameters as simulated (``parameters``),
        the full parameter set, the drive, the rig, the seed, warnings.
    """
    from ._identify import PHYSICAL

    b = run.bench
    return {
        "parameters": run.truth(),
        "units": {name: unit for name, (unit, _) in PHYSICAL.items()},
        "actuator": b.params.to_dict(),
        "derived": {"transmission_rad_per_m": b.params.transmission,
                    "reflected_mass_kg": b.params.reflected_mass,
                    "resonance_hz": b.params.resonance_hz,
                    "antiresonance_hz": b.params.antiresonance_hz},
        "loop": b.controller.to_dict(),
        "rig": {"f_ctrl": b.f_ctrl, "oversample": b.oversample, "aa_order": b.aa_order,
                "aa_cutoff": b.aa_cutoff, "bits": b.bits, "adc_range": b.adc_range,
                "current_range": b.current_range, "position_range": b.position_range,
                "current_noise": b.current_noise, "position_noise": b.position_noise,
                "voltage_bits": b.voltage_bits, "reference_lsb": b.reference_lsb,
                "f_ext": b.f_ext},
        "n_samples": run.raw.n_samples,
        "saturation": run.response.saturation_fraction(),
        "seed": run.seed,
        "warnings": list(run.warnings),
    }


def _format(format: str | RigFormat) -> RigFormat:
    if not isinstance(format, RigFormat):
        check_option("format", format, _FORMATS)
    return RigFormat.named(format)


def _check_targets(folder: str | os.PathLike[str], name: str, format: RigFormat,
                   overwrite: bool) -> tuple[Path, Path, Path]:
    root = as_path("folder", folder)
    as_bool("overwrite", overwrite)
    if not isinstance(name, str) or not name or "/" in name or os.sep in name:
        raise OptionTypeError(f"name must be a plain file stem, got {name!r}")
    targets = (root / f"{name}{format.suffixes[0]}", root / f"{name}.toml", root / "truth.json")
    for target in targets:
        check_writable(target, overwrite)
    return targets
