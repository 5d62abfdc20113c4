"""A virtual fleet of EMAs: one bench record per unit, a few bad, optionally wearing.

Manufacturing scatter around :data:`~servoid.plants.ema.TVC_EMA` (each a
normal distribution truncated at ±2.5σ, so a good unit stays good
whatever the seed; the test load ``m_L`` is the rig's, the same for all):

=========  ====  ==============================================
parameter  1σ    what it is
=========  ====  ==============================================
``K_m``    1.5 % magnets and winding
``R``      3 %   winding
``L``      3 %   winding
``J_m``    2 %   rotor, gear, screw
``b_m``    10 %  bearings, lubricant
``T_cm``   8 %   bearings, gear mesh, screw preload
``k_s``    4 %   nut preload, bearings, attachment
``c_s``    10 %  structural damping
``b_L``    8 %   rod seal
``F_cL``   8 %   rod seal, joints
=========  ====  ==============================================

Every ``bad_every``-th unit is built out of tolerance, in turn: a worn
screw (``k_s`` −35 %), a tight gear (``T_cm`` ×2.5) or weak magnets
(``K_m`` −12 %).  With ``drift`` the motor-side Coulomb friction grows by
that fraction per 100 days of test date (wear).  ``corrupt`` extra units
have a truncated rig file.  The fleet file's limits: K_m ±6 %, k_s ±20 %,
T_cm ±40 %, J_total ±5 % around nominal: good units pass with room for
their intervals, bad ones fail by a wide margin.
"""

from __future__ import annotations

import datetime as dt
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..._atomic import atomic_path
from ..._checks import as_bool, as_float, as_int, as_path
from ..._errors import DataError
from .._fleet import damage_file, scattered, truncated_normal, write_rows
from ._bench import EmaBench, bench_reference, run_bench, truth_parameters
from ._bench_files import write_run
from ._params import TVC_EMA

__all__ = ["FLEET_LIMITS", "FLEET_SCATTER", "EmaFleet", "write_fleet"]

#: 1σ relative scatter of the parameters (truncated at ±2.5σ).
FLEET_SCATTER = {"K_m": 0.015, "R": 0.03, "L": 0.03, "J_m": 0.02, "b_m": 0.10, "T_cm": 0.08,
                 "k_s": 0.04, "c_s": 0.10, "b_L": 0.08, "F_cL": 0.08}
#: Acceptance limits of the fleet file: relative tolerance around nominal.
FLEET_LIMITS = {"K_m": 0.06, "k_s": 0.20, "T_cm": 0.40, "J_total": 0.05}
_DEFECTS = (("worn screw: stiffness 35 % low", {"k_s": 0.65}),
            ("tight gear: motor-side Coulomb friction ×2.5", {"T_cm": 2.5}),
            ("weak magnets: motor constant 12 % low", {"K_m": 0.88}))


@dataclass(frozen=True)
class EmaFleet:
    """What :func:`write_fleet` wrote and the truth behind it.

    Attributes
    ----------
    folder : Path
        The fleet's folder.
    fleet_file, manifest, truth_file : Path
        ``fleet.toml``, ``units.csv`` and ``truth.csv``.
    bad : tuple of str
        Serials built out of tolerance.
    corrupt : tuple of str
        Serials whose rig file is damaged.
    """

    folder: Path
    fleet_file: Path
    manifest: Path
    truth_file: Path
    bad: tuple[str, ...]
    corrupt: tuple[str, ...]


def write_fleet(
    folder: str | os.PathLike[str],
    *,
    units: int = 12,
    seed: int = 0,
    bad_every: int = 6,
    corrupt: int = 0,
    drift: float = 0.0,
    duration: float = 4.0,
    overwrite: bool = False,
) -> EmaFleet:
    """Write bench records of many EMA units and their fleet file.

    Parameters
    ----------
    folder : path-like
        Output folder (created); one sub-folder per unit.
    units : int
        Good-or-bad units, 3..10 000.
    seed : int
        Seed of the scatter and of each record's noise.
    bad_every : int
        Every ``bad_every``-th unit is out of tolerance (0: none).
    corrupt : int
        Extra units whose rig file is truncated.
    drift : float
        Growth of the motor-side Coulomb friction per 100 days of test date
        (0.5: +50 %).
    duration : float
        Length of each unit's test [s] (half identifies, half validates).
    overwrite : bool
        Replace an earlier fleet's files.

    Returns
    -------
    EmaFleet
        The files written and which units are bad or damaged.
    """
    units = as_int("units", units, minimum=3, maximum=10_000)
    seed = as_int("seed", seed, minimum=0)
    bad_every = as_int("bad_every", bad_every, minimum=0)
    corrupt = as_int("corrupt", corrupt, minimum=0)
    drift = as_float("drift", drift)
    if abs(drift) > 5:
        raise DataError(f"drift must be a relative growth per 100 days within ±5, got {drift}")
    duration = as_float("duration", duration, positive=True, unit="s")
    as_bool("overwrite", overwrite)
    root = as_path("folder", folder)
    root.mkdir(parents=True, exist_ok=True)
    gen = np.random.default_rng(seed)
    base = EmaBench()
    reference = bench_reference(base, duration=duration)
    start = dt.date(2026, 3, 2)
    rows, truth, bad, damaged = [], [], [], []
    for k in range(units + corrupt):
        serial = f"EMA-{k + 1:04d}"
        date = start + dt.timedelta(days=k)
        factors = {name: 1.0 + s * truncated_normal(gen) for name, s in FLEET_SCATTER.items()}
        defect = ""
        if bad_every and k % bad_every == bad_every - 1 and k < units:
            defect, change = _DEFECTS[(k // bad_every) % len(_DEFECTS)]
            factors = {n: f * change.get(n, 1.0) for n, f in factors.items()}
            bad.append(serial)
        factors["T_cm"] *= 1.0 + drift * (date - start).days / 100.0
        params = scattered(TVC_EMA, factors)
        run = run_bench(base.with_(params=params), reference, rng=seed * 100_003 + k)
        files = write_run(run, root / "units" / serial, overwrite=overwrite)
        if k >= units:
            damage_file(files[0])
            damaged.append(serial)
        rows.append({"path": files[1].relative_to(root).as_posix(), "serial": serial,
                     "date": date.isoformat(), "rig": "virtual EMA bench"})
        truth.append({"serial": serial, "date": date.isoformat(),
                      **truth_parameters(params),
                      "defect": defect or ("corrupt file" if k >= units else "")})
    manifest = write_rows(root / "units.csv", rows, overwrite)
    truth_file = write_rows(root / "truth.csv", truth, overwrite)
    fleet_file = root / "fleet.toml"
    with atomic_path(fleet_file, overwrite=overwrite) as tmp:
        tmp.write_text(_fleet_toml(drift), encoding="utf-8")
    return EmaFleet(root, fleet_file, manifest, truth_file, tuple(bad), tuple(damaged))






def _fleet_toml(drift: float) -> str:
    nominal = truth_parameters(TVC_EMA)
    limits = "\n".join(
        f"[limits.{name}]\nnominal = {nominal[name]!r}\ntolerance_percent = {100 * tol:g}\n"
        for name, tol in FLEET_LIMITS.items())
    note = (f"# wear: motor-side Coulomb friction grows {100 * drift:g} % per 100 days\n"
            if drift and math.isfinite(drift) else "")
    return (
        "# A virtual fleet of EMA units (servoid bench ema-fleet); truth in truth.csv.\n"
        "# Each record's own [identify] (method = \"ema\", the transmission) is used.\n"
        f"{note}"
        "[records]\nmanifest = \"units.csv\"\n\n"
        f"{limits}\n"
        "[trend]\nby = \"date\"\n\n"
        "[report]\nfolder = \"fleet-results\"\n"
    )
