"""The demo: study 1 end to end on a virtual bench.

The Set-B electro-hydraulic servo actuator (1500 kg load, mechanical
position feedback) is tested on the virtual bench with the PRBS of the
models specification (§4: n = 11, 10 samples per bit, 20 470 samples at
1 kHz, 30 dB SNR, fixed seed) at the largest amplitude the actuator can run
(:func:`~servoid.plants.ehsa.within_limits`: ±0.19 mm, where the spec's
±1 mm would ask a load pressure of 35 MPa from a 21 MPa supply). The bench writes what a LabVIEW rig writes
— a TDMS file in volts at 5 kHz and a matching experiment TOML — and
:func:`~servoid.workflows.identify` runs the closed-loop workflow on those
files exactly as on a real record: the two-step indirect approach and the
one-step output-error fit of K, ω_hp and δ_hp with confidence intervals,
validated on the held-back half. Every printed number comes from the run.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..._checks import as_int
from ..._errors import OutputExistsError
from ..._lock import hold_folder
from ..._words import option
from ...signals import prbs
from ...workflows import identify
from ...workflows.kit import Displayed
from ._bench import BenchRun, run
from ._bench_config import EhsaBench
from ._bench_files import write_bench_files
from ._limits import within_limits
from ._workflow import ClosedLoopIdentification

__all__ = ["DemoResult", "run_demo"]


@dataclass(frozen=True, eq=False, repr=False)
class DemoResult(Displayed):
    """The demo's bench run and identification."""

    bench_run: BenchRun
    identification: ClosedLoopIdentification
    rig_files: tuple[Path, ...]

    def verdict(self) -> Any:
        """The identification's verdict (:meth:`ClosedLoopIdentification.verdict`)."""
        return self.identification.verdict()

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``--json``."""
        ident = self.identification
        return {
            "rig_files": [str(p) for p in self.rig_files],
            "truth": dict(ident.truth or {}),
            "parameters": ident.table(),
            "validation_fit_percent": {a: v.fit_percent for a, v in ident.validations.items()},
            "notes": list(ident.notes),
            "verdict": ident.verdict().to_dict(),
            "report": str(ident.folder / "report.html") if ident.folder else None,
            "files": [str(f) for f in ident.files],
        }

    def __str__(self) -> str:
        run_ = self.bench_run
        ex = run_.excitation
        head = [
            "servoid demo — study 1: electro-hydraulic servo actuator in closed loop (Set B)",
            f"  virtual bench: PRBS n = {ex.description['n']}, {ex.clock} samples/bit, "
            f"±{ex.amplitude * 1e3:g} mm, {ex.n_samples} samples at {1 / ex.dt:g} Hz, "
            f"SNR {run_.snr_db:g} dB, seed {run_.seed}",
            f"  rig files: {', '.join(str(p) for p in self.rig_files)}",
            "",
        ]
        return "\n".join(head) + str(self.identification)


_MARKER = ".servoid-demo"


def run_demo(
    out: str | os.PathLike[str] = "servoid-demo",
    *,
    seed: int = 2026,
    snr_db: float = 30.0,
    overwrite: bool = False,
) -> DemoResult:
    """Run the study-1 demo and write its folder.

    Parameters
    ----------
    out : path
        Folder for the rig files and the report. Files of an earlier demo
        run there (the folder holds the demo's marker file) are replaced; a
        non-empty folder without the marker is refused unless ``overwrite``.
    seed : int
        Seed of the bench's noise.
    snr_db : float
        Signal-to-noise ratio of the position at 1 kHz [dB].
    overwrite : bool
        Write into a non-empty folder that is not an earlier demo's.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputExistsError(f"{out} is a file; the demo writes a folder of files: choose "
                                "another --out")
    if out.is_dir() and any(out.iterdir()) and not (out / _MARKER).exists() and not overwrite:
        raise OutputExistsError(
            f"{out} is not empty and holds no earlier demo: the demo would replace files "
            f"there. Choose another {option('out', '--out')} or pass "
            f"{option('overwrite=True', '--overwrite')}"
        )
    seed = as_int("seed", seed, minimum=0)
    bench = EhsaBench(snr_db=snr_db)  # what can be refused is refused before the folder exists
    # the spec's PRBS scaled to a test the actuator can run (±0.19 mm for Set B: at ±1 mm the
    # load would need 35 MPa from its 21 MPa supply)
    excitation = within_limits(bench.params, prbs(11, clock=10, amplitude=1e-3, dt=bench.dt))
    # the outermost folder this call creates: on failure it goes, with what the call wrote
    created = next((p for p in (*reversed(out.parents), out) if not p.exists()), None)
    with hold_folder(out):  # one demo at a time in a folder
        try:
            (out / _MARKER).write_text("written by servoid demo; its files here may be "
                                       "replaced\n")
            record = run(bench, excitation, rng=seed)
            files = write_bench_files(record, out, format="tdms", overwrite=True)
            toml = next(p for p in files if p.suffix == ".toml")
            result = identify(toml, out / "report", overwrite=True)
        except BaseException:
            if created is not None:  # a folder this call made holds only this call's files
                shutil.rmtree(created, ignore_errors=True)
            raise
    if not isinstance(result, ClosedLoopIdentification):  # the bench's TOML asks for closedloop
        raise TypeError(f"the demo's experiment file gave {type(result).__name__}")
    return DemoResult(record, result, tuple(files))
