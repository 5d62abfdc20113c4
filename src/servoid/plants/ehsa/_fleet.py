"""A virtual fleet: bench records of many EHSA units, a few bad, optionally ageing.

Manufacturing scatter (each a normal distribution truncated at ±2.5σ, so
that a good unit stays a good unit whatever the seed), around Set B:

=================  =========  ===========================================
parameter          1σ         what it moves
=================  =========  ===========================================
``w`` (valve)      1.5 %      K ∝ w
``beta_e``         2 %        ω_hp ∝ √β_e, δ_hp
``V_t``            1 %        ω_hp ∝ 1/√V_t, δ_hp
``K_ce`` (leak)    8 %        δ_hp
=================  =========  ===========================================

so K scatters 1.5 %, ω_hp about 1.1 % and δ_hp about 7 %.  Every
``bad_every``-th unit is built outside tolerance, in turn: a valve with
20 % less area gradient (K −20 %), air in the oil (β_e −45 %, ω_hp −26 %)
or a worn seal (K_ce ×3, δ_hp about ×2.3).  With ``drift`` the leakage of
every unit grows by that fraction per 100 days of the test date (seal
wear), so δ_hp rises across the fleet's dates.  ``corrupt`` extra records
have a truncated rig file.

The fleet file's limits are nominal ± 8 % on K, ± 6 % on ω_hp and ± 40 %
on δ_hp: good units (within 2.5σ) pass with room for their intervals, bad
units fail by a wide margin.
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..._atomic import atomic_path, check_writable
from ..._checks import as_path
from ..._errors import DataError
from ..._progress import Progress
from ...data import RigFormat
from ._bench import run
from ._bench_config import EhsaBench
from ._bench_files import write_bench_files
from ._params import SET_B, EhsaParameters

__all__ = ["FLEET_LIMITS", "FLEET_SCATTER", "VirtualFleet", "write_virtual_fleet"]

#: 1σ relative scatter of the physical parameters (truncated at ±2.5σ).
FLEET_SCATTER = {"w": 0.015, "beta_e": 0.02, "V_t": 0.01, "K_ce": 0.08}
#: Acceptance limits of the fleet file: relative tolerance around Set B.
FLEET_LIMITS = {"K": 0.08, "omega_hp": 0.06, "delta_hp": 0.40}
_DEFECTS = (("valve area gradient 20 % low", {"w": 0.80}),
            ("air in the oil: bulk modulus 45 % low", {"beta_e": 0.55}),
            ("worn seal: leakage ×3", {"K_ce": 3.0}))
_TRUNCATE = 2.5


@dataclass(frozen=True)
class VirtualFleet:
    """What :func:`write_virtual_fleet` wrote and the truth behind it.

    Attributes
    ----------
    folder : Path
    fleet_file, manifest, truth_file : Path
    bad : tuple of str
        Serials built outside tolerance.
    corrupt : tuple of str
        Serials whose rig file is damaged.
    """

    folder: Path
    fleet_file: Path
    manifest: Path
    truth_file: Path
    bad: tuple[str, ...]
    corrupt: tuple[str, ...]


def write_virtual_fleet(
    folder: str | os.PathLike[str],
    *,
    units: int = 24,
    seed: int = 0,
    drift: float = 0.0,
    bad_every: int = 8,
    corrupt: int = 1,
    register: int = 9,
    clock: int = 10,
    snr_db: float = 35.0,
    overwrite: bool = False,
) -> VirtualFleet:
    """Write a virtual fleet: records, manifest, truth, fleet file.

    One bench record per EHSA unit (``units`` of them), their manifest, the
    truth and the fleet file.

    Parameters
    ----------
    folder : path-like
        Output folder (created); one sub-folder per unit.
    units : int
        Number of good-or-bad units, 3..100 000.
    seed : int
        Seed of the scatter and of each record's noise.
    drift : float
        Relative growth of the leakage per 100 days of test date (0: none).
    bad_every : int
        Every `bad_every`-th unit is outside tolerance (0: none).
    corrupt : int
        Extra units whose rig file is truncated.
    register, clock : int
        PRBS register length and clock of each test (at 1 kHz).
    snr_db : float
        Position SNR of each record [dB].
    overwrite : bool
        Replace an earlier virtual fleet's files.
    """
    if isinstance(units, bool) or not isinstance(units, int) or not 3 <= units <= 100_000:
        raise DataError(f"units must be a whole number from 3 to 100000 (--units); got {units!r}")
    if not math.isfinite(drift) or abs(drift) > 5:
        raise DataError(f"drift must be a relative leakage growth per 100 days within ±5 "
                        f"(--drift); got {drift!r}")
    if isinstance(corrupt, bool) or not isinstance(corrupt, int) or corrupt < 0:
        raise DataError(f"corrupt must be a whole number >= 0 (--corrupt); got {corrupt!r}")
    if isinstance(bad_every, bool) or not isinstance(bad_every, int) or bad_every < 0:
        raise DataError(f"bad_every must be a whole number >= 0; got {bad_every!r}")
    from ...signals import prbs

    root = as_path("folder", folder)
    for name in ("units.csv", "truth.csv", "fleet.toml"):  # refused before any unit is written
        check_writable(root / name, overwrite)
    root.mkdir(parents=True, exist_ok=True)
    gen = np.random.default_rng(seed)
    excitation = prbs(register, clock=clock, amplitude=1e-3, periods=1, dt=1e-3)
    start = dt.date(2026, 1, 5)
    rows, truth, bad, damaged = [], [], [], []
    bar = Progress(units + corrupt, "simulating units", failures=False)  # the command line's
    for k in range(units + corrupt):
        serial = f"SN-{k + 1:04d}"
        date = start + dt.timedelta(days=k)
        factors = {name: 1.0 + sigma * _truncated(gen) for name, sigma in FLEET_SCATTER.items()}
        defect = ""
        if bad_every and k % bad_every == bad_every - 1 and k < units:
            defect, change = _DEFECTS[(k // bad_every) % len(_DEFECTS)]
            factors = {n: f * change.get(n, 1.0) for n, f in factors.items()}
            bad.append(serial)
        age = (date - start).days / 100.0
        factors["K_ce"] *= 1.0 + drift * age
        params = _unit(SET_B, factors)
        unit_dir = root / "units" / serial
        record = run(EhsaBench(params=params, snr_db=snr_db), excitation,
                     rng=int(seed) * 100_003 + k)
        files = write_bench_files(record, unit_dir, overwrite=overwrite)
        if k >= units:
            _truncate(next(f for f in files if RigFormat.find(f) is not None))
            damaged.append(serial)
        toml = next(f for f in files if f.suffix == ".toml")
        rows.append({"path": toml.relative_to(root).as_posix(), "serial": serial,
                     "date": date.isoformat(), "rig": "virtual bench B"})
        truth.append({"serial": serial, "date": date.isoformat(), "K": params.K,
                      "omega_hp": params.omega_hp, "delta_hp": params.delta_hp,
                      "defect": defect or ("corrupt file" if k >= units else ""),
                      **{f"factor_{n}": f for n, f in factors.items()}})
        bar.update()
    bar.close()
    manifest = _write_csv(root / "units.csv", rows, overwrite)
    truth_file = _write_csv(root / "truth.csv", truth, overwrite)
    fleet_file = root / "fleet.toml"
    with atomic_path(fleet_file, overwrite=overwrite) as tmp:
        tmp.write_text(_fleet_toml(drift), encoding="utf-8")
    return VirtualFleet(root, fleet_file, manifest, truth_file, tuple(bad), tuple(damaged))


def _truncated(gen: np.random.Generator) -> float:
    while True:
        z = float(gen.standard_normal())
        if abs(z) <= _TRUNCATE:
            return z


def _unit(base: EhsaParameters, factors: dict[str, float]) -> EhsaParameters:
    return base.with_(**{name: getattr(base, name) * f for name, f in factors.items()})


def _truncate(path: Path) -> None:
    data = path.read_bytes()
    with atomic_path(path, overwrite=True) as tmp:
        tmp.write_bytes(data[: len(data) // 3])


def _write_csv(path: Path, rows: list[dict[str, object]], overwrite: bool) -> Path:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    with atomic_path(path, overwrite=overwrite) as tmp:
        tmp.write_text(buffer.getvalue(), encoding="utf-8")
    return path


def _fleet_toml(drift: float) -> str:
    limits = "\n".join(
        f"[limits.{name}]\nnominal = {getattr(SET_B, name)!r}\ntolerance_percent = "
        f"{100 * tol:g}\n" for name, tol in FLEET_LIMITS.items())
    note = (f"# ageing: leakage grows {100 * drift:g} % per 100 days of test date\n"
            if drift else "")
    return (
        "# A virtual fleet of EHSA units (servoid bench fleet); truth in truth.csv\n"
        f"{note}"
        "[records]\nmanifest = \"units.csv\"\n\n"
        "[identify]\nmethod = \"closedloop\"\napproach = \"one-step\"\n"
        "structure_test = false\n\n"
        f"{limits}\n"
        "[trend]\nby = \"date\"\n\n"
        "[report]\nfolder = \"fleet-results\"\n"
    )

