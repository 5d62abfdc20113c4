"""Write a pneumatic test campaign as a real rig would.

One folder, every file written atomically and none overwritten unless
asked (all targets are checked before the first is written):

* ``<test>.tdms`` or ``<test>.csv`` per test: the raw channels in volts
  at ``f_acq``;
* ``<test>.toml`` per test: the experiment file that calibrates the
  channels back to SI under their servoid names (absolute pressures are
  not detrended) and splits the record in halves;
* ``pneumatic.toml``: the campaign file.  Its ``[data]`` is the
  validation record; ``[identify]`` holds ``method =
  "pneumatic-multistep"``, one key per test naming its TOML, the options
  the rig's records call for (``derivatives = "measured"``,
  ``valve_u_hold = "cubic"``) and the table ``[identify.known]`` of the
  constants the identification may use (A_I, A_II, V_0I, V_0II, m_k, p_S,
  p_R, p_amb, T_S, g) with the hot-wire's lag ``mdot_sensor_bandwidth``;
* ``truth.json``: every true parameter, the known constants, the rig
  and, per test, its design, noise levels and warnings.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..._atomic import atomic_path, check_writable
from ..._checks import as_bool, as_instance, as_int, as_path, as_str, type_error
from ..._errors import DataError, OptionTypeError, ServoidWarning, check_option
from ..._warn import warn
from ...data import Experiment, RigFormat, write_experiment_spec
from ._bench import (
    _TEST_NAMES,
    PNEUMATIC_CHANNELS,
    PNEUMATIC_TESTS,
    PneumaticBench,
    PneumaticRun,
    PneumaticTest,
    PneumaticTestName,
    run_pneumatic,
)
from ._params import PNEUMATIC_NOMINAL, PneumaticParameters

__all__ = ["write_pneumatic_campaign"]

#: The formats the bench writes, its default first.
_FORMATS = RigFormat.writable(first="tdms")
#: Parameters the multi-step scheme estimates (spec §3.9).
IDENTIFIED = ("k_v", "xi_v", "omega_v", "ad_1", "ad_2", "ad_3", "ad_4", "R", "kappa",
              "F_haft", "v_krit", "c_k", "d_k", "p_krit")
#: Constants the identification takes as known.
KNOWN = ("A_I", "A_II", "V_0I", "V_0II", "m_k", "p_S", "p_R", "p_amb", "T_S", "g")
_UNITS = {
    "k_v": "m/V", "xi_v": "-", "omega_v": "rad/s", "ad_1": "m", "ad_2": "m", "ad_3": "m",
    "ad_4": "m", "R": "J/(kg·K)", "kappa": "-", "F_haft": "N", "v_krit": "m/s",
    "c_k": "N·s/m", "d_k": "N", "p_krit": "-", "A_I": "m²", "A_II": "m²", "V_0I": "m³",
    "V_0II": "m³", "m_k": "kg", "p_S": "Pa", "p_R": "Pa", "p_amb": "Pa", "T_S": "K",
    "g": "m/s²",
}
CAMPAIGN = "pneumatic.toml"
METHOD = "pneumatic-multistep"


def write_pneumatic_campaign(
    folder: str | os.PathLike[str],
    *,
    params: PneumaticParameters = PNEUMATIC_NOMINAL,
    tests: Sequence[PneumaticTestName | PneumaticTest] = _TEST_NAMES,
    snr_db: float | None = 40.0,
    seed: int = 0,
    format: str | RigFormat = "tdms",
    overwrite: bool = False,
    duration: float | None = None,
    f_acq: float = 10_000.0,
) -> list[Path]:
    """Run the multi-step test campaign and write its files.

    Parameters
    ----------
    folder : path-like
        Output folder, created if missing.
    params : PneumaticParameters
        The actuator (the truth); pressures absolute.
    tests : sequence of str or PneumaticTest
        Tests to run, each once, by name (:data:`PNEUMATIC_TESTS`) or as
        a :class:`PneumaticTest`; names among "valve", "thermo", "flow",
        "friction", "validation".
    snr_db : float or None
        SNR of every sensor channel at `f_acq` [dB]; None: quantisation only.
    seed : int
        Noise seed, >= 0.  Each test draws from ``default_rng([seed, k])``
        with k its index in the list of names above, so a test's record
        does not depend on which other tests run.
    format : {"tdms", "csv"} or RigFormat
        Rig file format (one :data:`~servoid.data.RIG_FORMATS` writes).
    overwrite : bool
        Replace existing files; otherwise :class:`OutputExistsError`
        before anything is written.
    duration : float, optional
        Record length of every test [s]; default each test's own (2 s
        valve, 4 s the others).
    f_acq : float
        Acquisition rate [Hz]; below 10 kHz a warning.

    Returns
    -------
    list of pathlib.Path
        Per test its rig file and TOML, then ``pneumatic.toml`` and
        ``truth.json``.

    Raises
    ------
    OptionError
        A test name outside the list (the message lists the valid ones)
        or an unknown format.
    DataError
        A test given twice, a non-finite SNR, a negative seed, a
        non-absolute pressure.
    OutputExistsError
        A target exists and `overwrite` is False.

    Warns
    -----
    ServoidWarning
        As :func:`run_pneumatic`, each message once.

    Notes
    -----
    ``pneumatic.toml``'s ``[data]`` is the validation record when it is
    among `tests`, else the last test's; ``[identify]`` names only the
    tests written.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     files = write_pneumatic_campaign(tmp, tests=["valve"], duration=0.1)
    ...     [p.name for p in files]
    ['valve.tdms', 'valve.toml', 'pneumatic.toml', 'truth.json']
    """
    folder = as_path("folder", folder)
    as_bool("overwrite", overwrite)
    if not isinstance(format, RigFormat):
        check_option("format", format, _FORMATS)
    fmt = RigFormat.named(format)
    seed = as_int("seed", seed, minimum=0)
    if snr_db is not None and not (isinstance(snr_db, (int, float))
                                   and not isinstance(snr_db, bool) and math.isfinite(snr_db)):
        raise DataError(f"snr_db must be a finite number of dB (or None), got {snr_db!r}")
    plan = _plan(tests, duration)
    bench = PneumaticBench(params=params, f_acq=f_acq, snr_db=snr_db)
    names = [t.name for t in plan]
    targets = [folder / f"{n}{ext}" for n in names for ext in (fmt.suffixes[0], ".toml")]
    targets += [folder / CAMPAIGN, folder / "truth.json"]
    for target in targets:
        check_writable(target, overwrite)

    # Simulate everything before writing anything (a failing test leaves no
    # half campaign), but keep only what the files need: the simulator's
    # analog-rate output of a 10 s test is ≈ 60 MB.
    records: list[tuple[Experiment, dict[str, Any], dict[str, Any]]] = []
    issued: list[str] = []
    for test in plan:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            rec = run_pneumatic(bench, test, rng=np.random.default_rng(
                [int(seed), _TEST_NAMES.index(test.name)]))
        for w in caught:
            text = str(w.message)
            if text not in issued:
                issued.append(text)
                warn(text, ServoidWarning)
        doc = pneumatic_experiment_document(rec, f"{test.name}{fmt.suffixes[0]}")
        records.append((rec.raw, doc, _test_info(rec)))
        del rec

    folder.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for raw, doc, _ in records:
        rig = folder / doc["data"]["file"]
        toml = rig.with_suffix(".toml")
        fmt.write(raw, rig, overwrite=overwrite)
        write_experiment_spec(doc, toml, overwrite=overwrite)
        written += [rig, toml]
    infos = {info["name"]: info for _, _, info in records}
    campaign = dict(next((d for _, d, i in records if i["name"] == "validation"),
                         records[-1][1]))
    campaign["identify"] = {
        "method": METHOD,
        **{name: f"{name}.toml" for name in infos},
        **identify_options(bench),
        "known": {**known_constants(params), **known_sensor_dynamics(bench)},
    }
    write_experiment_spec(campaign, folder / CAMPAIGN, overwrite=overwrite)
    truth = folder / "truth.json"
    text = json.dumps(_truth(bench, infos, int(seed), issued), indent=2,
                      ensure_ascii=False) + "\n"
    with atomic_path(truth, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return [*written, folder / CAMPAIGN, truth]


def known_constants(params: PneumaticParameters) -> dict[str, float]:
    """Return the constants the identification takes as known [SI]."""
    return {k: float(getattr(params, k)) for k in KNOWN}


def known_sensor_dynamics(bench: PneumaticBench) -> dict[str, float]:
    """Return the rig's sensor dynamics the identification must know.

    The hot-wire's first-order lag [Hz]: the flow equations are static in
    x_v and p, so S0/S2/S3 pass their regressors through the same lag
    (uncompensated it moves p_krit from 0.25 to 0.48 on this rig).  The
    anti-alias filter acts on every channel alike and needs no entry.
    """
    return {"mdot_sensor_bandwidth": float(bench.flow_bandwidth)}


def identify_options(bench: PneumaticBench) -> dict[str, str]:
    """Return the ``[identify]`` options this rig's records call for.

    * ``derivatives = "measured"``: the rig has velocity and acceleration
      sensors.  At the default 40 dB the position noise (0.14 mm on the
      friction test) differentiated twice by the SVF drowns the friction
      law (c_k −96 %, checked); the sensors give ẋ_k, ẍ_k at 40 dB each.
    * ``valve_u_hold = "cubic"``: the recorded u passed the anti-alias
      filter like every channel, so it is not the DAC's staircase that
      "zoh" assumes (which biases ω_v by +1.3 % at 10 kHz).
    """
    del bench  # the same for every configuration of this rig
    return {"derivatives": "measured", "valve_u_hold": "cubic"}


def pneumatic_experiment_document(run: PneumaticRun, file: str) -> dict[str, Any]:
    """Return the experiment TOML of one test as a dictionary.

    Parameters
    ----------
    run : PneumaticRun
        The test's run.
    file : str
        The rig file, relative to the TOML's folder.

    Returns
    -------
    dict
        TOML-shaped, for :func:`servoid.data.write_experiment_spec`.
    """
    as_instance("run", run, PneumaticRun, "a PneumaticRun (from servoid.plants.pneumatic.run_pneumatic)")
    data: dict[str, Any] = {"file": as_str("file", file)}
    fmt = RigFormat.find(file)
    if fmt is not None and fmt.time is not None:  # the time column its writer wrote
        data["time"] = fmt.time
    channels = {}
    for name, (gain, offset) in run.calibration().items():
        role, unit = PNEUMATIC_CHANNELS[name]
        # 15 significant digits: 1/(10 V/0.125 m) prints as 0.0125, not ...0001.
        channels[name] = {"source": name, "role": role, "gain": float(f"{gain:.15g}"),
                          "offset": float(f"{offset:.15g}"), "unit": unit}
    doc: dict[str, Any] = {
        "data": data,
        "channels": channels,
        # Absolute pressures and temperatures carry the physics: no detrending.
        "preprocess": {"detrend": "none"},
        "split": {"fraction": 0.5},
    }
    c = run.test.controller
    if c is not None:
        doc["loop"] = {"K_p": c.K_p, "K_d": c.K_d, "u_max": run.bench.params.u_max}
    doc["report"] = {"truth": "truth.json"}
    return doc


def pneumatic_truth_document(runs: Sequence[PneumaticRun], seed: int | None,
                             warnings_issued: Sequence[str] = ()) -> dict[str, Any]:
    """Return the content of ``truth.json`` for a campaign.

    Parameters
    ----------
    runs : sequence of PneumaticRun
        The campaign's runs, on one bench.
    seed : int or None
        The campaign seed.
    warnings_issued : sequence of str
        The campaign's warnings.

    Returns
    -------
    dict
        JSON-ready: the identified parameters and the known constants at
        the top level, all parameters, units, the rig and every test.
    """
    if isinstance(runs, (str, bytes)) or not isinstance(runs, Sequence) or not runs or not all(
            isinstance(r, PneumaticRun) for r in runs):
        raise type_error("runs", runs, "a non-empty list of PneumaticRun")
    if seed is not None:
        seed = as_int("seed", seed, minimum=0)
    return _truth(runs[0].bench, {r.test.name: _test_info(r) for r in runs}, seed,
                  warnings_issued)


# -- private helpers ---------------------------------------------------------


def _test_info(r: PneumaticRun) -> dict[str, Any]:
    return {
        **r.test.to_dict(),
        "n_samples": r.raw.n_samples,
        "channels": list(r.channels),
        "signal_rms": r.signal_rms,
        "noise_std": r.noise_std,
        "quantisation_std": r.quantisation_std,
        "sensor_noise_std": r.sensor_noise_std,
        "hot_wire_saturation": r.saturation,
        "dt_int": r.response.dt_int,
        "warnings": list(r.warnings),
    }


def _truth(b: PneumaticBench, tests: dict[str, dict[str, Any]], seed: int | None,
           warnings_issued: Sequence[str]) -> dict[str, Any]:
    p = b.params
    identified = {k: float(getattr(p, k)) for k in IDENTIFIED}
    known = known_constants(p)
    parameters = {k: float(v) for k, v in vars(p).items()}
    rig = {
        "f_acq": b.f_acq, "dt": b.dt, "oversample": b.oversample, "aa_order": b.aa_order,
        "aa_cutoff": b.aa_cutoff, "bits": b.bits, "adc_range": b.adc_range, "lsb": b.lsb,
        "snr_db": b.snr_db, "noise_std": None if b.noise_std is None else dict(b.noise_std),
        "temperature_noise": b.temperature_noise, "flow_limit": b.flow_limit,
        "flow_bandwidth": b.flow_bandwidth, "position_range": b.position_range,
        "spool_range": b.spool_range, "pressure_range": b.pressure_range,
        "velocity_range": b.velocity_range, "acceleration_range": b.acceleration_range,
        "force_range": b.force_range, "temperature_sensitivity": b.temperature_sensitivity,
        "sensitivities": b.sensitivities(),
        "calibration": {k: {"gain": g, "offset": o} for k, (g, o) in b.calibration().items()},
        "flow_function": b.flow, "blend_friction": b.blend,
        "units": {k: u for k, (_, u) in PNEUMATIC_CHANNELS.items()},
    }
    return {
        "rig_kind": "pneumatic",
        **identified,
        **known,
        "identified": list(IDENTIFIED),
        "known": known,
        "units": dict(_UNITS),
        "parameters": parameters,
        "snr_db": b.snr_db,
        "seed": seed,
        "rig": rig,
        "tests": tests,
        "warnings": list(warnings_issued),
    }


def _plan(tests: object, duration: float | None) -> list[PneumaticTest]:
    if isinstance(tests, (str, PneumaticTest)) or not isinstance(tests, Sequence):
        raise OptionTypeError(f"tests must be a sequence of test names or PneumaticTest, "
                              f"got {tests!r}")
    if not tests:
        raise DataError("tests must name at least one test")
    plan: list[PneumaticTest] = []
    for t in tests:
        if isinstance(t, str):
            check_option("test", t, _TEST_NAMES)
            test = PNEUMATIC_TESTS[t]
        elif isinstance(t, PneumaticTest):
            test = t
        else:
            raise OptionTypeError(f"tests must hold test names or PneumaticTest, got {t!r}")
        if duration is not None:
            test = test.with_duration(duration)
        if any(q.name == test.name for q in plan):
            raise DataError(f"test {test.name!r} is listed twice; each test is one record")
        plan.append(test)
    return plan
