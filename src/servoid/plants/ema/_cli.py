"""``servoid bench ema`` and ``servoid bench ema-fleet``: the EMA's rig commands.

Only argparse at import: the command line builds its parser (and answers
``--help``) without the numerics; the bench loads when a command runs.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ...data import RigFormat  # the format records only: no numerics

__all__ = ["add_cli"]

# the bench's parameters → the flags that set them, for its error messages
_WORDS = {"duration": "--duration", "amplitude": "--amplitude", "sweep": "--sweep",
          "f_max": "--fmax", "seed": "--seed", "units": "--units", "bad_every": "--bad-every",
          "corrupt": "--corrupt", "drift": "--drift", "position_noise": "--lvdt-noise",
          "bits": "--bits"}


def add_cli(rigs: Any, json_flag: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``bench ema`` and ``bench ema-fleet`` to the bench's rigs."""
    ema = rigs.add_parser(
        "ema", help="electromechanical actuator: motor, gearbox, ball screw, cascaded drive",
        description="Run the identification test of an EMA (the nominal TVC-class actuator, "
        "docs/ema.md) on a virtual rig: a 10 kHz drive with current, speed and position "
        "loops, a slow sweep over the stroke with a multisine on top, and a logger clocked by "
        "the drive (current sensor and LVDT through a 4th-order Butterworth anti-alias filter "
        "at 2 kHz and a 16-bit ADC; voltage command, encoder and reference in counts). "
        "Writes ema.tdms|csv, ema.toml (method = \"ema\") and truth.json.")
    ema.add_argument("--out", type=Path, required=True,
                     help="output folder for ema.tdms|csv, ema.toml and truth.json")
    ema.add_argument("--duration", type=float, default=8.0,
                     help="test length [s]; half identifies, half validates "
                     "(default: %(default)g)")
    ema.add_argument("--amplitude", type=float, default=2e-3,
                     help="multisine peak [m] (default: %(default)g)")
    ema.add_argument("--sweep", type=float, default=0.02,
                     help="slow sweep amplitude [m] (default: %(default)g)")
    ema.add_argument("--fmax", type=float, default=40.0,
                     help="highest multisine line [Hz] (default: %(default)g)")
    ema.add_argument("--lvdt-noise", type=float, default=4e-6,
                     help="LVDT noise, std at the analog rate [m] (default: %(default)g)")
    ema.add_argument("--bits", type=int, default=16,
                     help="ADC resolution of the current sensor and the LVDT, 8..24 "
                     "(default: %(default)s)")
    ema.add_argument("--backlash", type=float, default=0.0,
                     help="screw backlash [m], which the identification does not model "
                     "(default: %(default)g)")
    ema.add_argument("--seed", type=int, default=0, help="noise seed (default: %(default)s)")
    ema.add_argument("--format", choices=RigFormat.writable(first="tdms"), default="tdms",
                     help="rig file format (default: %(default)s)")
    ema.add_argument("--overwrite", action="store_true",
                     help="replace files of an earlier run in --out")
    json_flag(ema)
    ema.set_defaults(run=_run_ema)

    fleet = rigs.add_parser(
        "ema-fleet", help="a virtual fleet of EMA units (for servoid fleet)",
        description="Write bench records of many EMA units with manufacturing scatter (motor "
        "constant 1.5 %, screw stiffness 4 %, frictions 8-10 %, ..., 1 sigma truncated at "
        "2.5 sigma), every --bad-every-th unit out of tolerance (worn screw, tight gear or "
        "weak magnets in turn), an optional wear drift of the motor friction and --corrupt "
        "damaged files; plus units.csv, truth.csv and fleet.toml with acceptance limits. "
        "Then: servoid fleet OUT/fleet.toml.")
    fleet.add_argument("--out", type=Path, default=Path("servoid-ema-fleet"),
                       help="folder (default: %(default)s)")
    fleet.add_argument("--units", type=int, default=12, help="units (default: %(default)s)")
    fleet.add_argument("--bad-every", type=int, default=6,
                       help="every Nth unit is out of tolerance; 0: none (default: %(default)s)")
    fleet.add_argument("--corrupt", type=int, default=0,
                       help="extra records with a truncated rig file (default: %(default)s)")
    fleet.add_argument("--drift", type=float, default=0.0,
                       help="motor friction growth per 100 days of test date, e.g. 0.5 for "
                       "+50 %% (default: %(default)s)")
    fleet.add_argument("--duration", type=float, default=4.0,
                       help="test length of each unit [s] (default: %(default)g)")
    fleet.add_argument("--seed", type=int, default=0, help="seed (default: %(default)s)")
    fleet.add_argument("--overwrite", action="store_true",
                       help="replace an earlier fleet's files")
    json_flag(fleet)
    fleet.set_defaults(run=_run_fleet)


def _run_ema(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    import json
    import warnings

    from ..._progress import stage
    from ...cli._flags import at_least, finite, folder_out, in_flags, positive
    from ._bench import EmaBench
    from ._bench_files import write_bench
    from ._params import TVC_EMA

    positive("--duration", args.duration, "s")
    positive("--fmax", args.fmax, "Hz")
    finite("--amplitude", args.amplitude, "m")
    finite("--sweep", args.sweep, "m")
    finite("--lvdt-noise", args.lvdt_noise, "m")
    finite("--backlash", args.backlash, "m")
    at_least("--seed", args.seed, 0)
    folder_out("--out", args.out)
    start = time.perf_counter()
    with warnings.catch_warnings(), in_flags(_WORDS), \
            stage(f"simulating the EMA bench ({args.duration:g} s at 10 kHz)"):
        warnings.simplefilter("ignore")  # kept in truth.json and printed below
        bench = EmaBench(params=TVC_EMA.with_(backlash=args.backlash),
                         position_noise=args.lvdt_noise, bits=args.bits)
        files = write_bench(args.out, bench=bench, seed=args.seed, duration=args.duration,
                            amplitude=args.amplitude, sweep=args.sweep, f_max=args.fmax,
                            format=args.format, overwrite=args.overwrite)
    elapsed = time.perf_counter() - start
    truth = json.loads(files[-1].read_text(encoding="utf-8"))
    derived = truth["derived"]
    payload = {"files": [str(f) for f in files], "n_samples": truth["n_samples"],
               "f_ctrl": truth["rig"]["f_ctrl"], "seed": truth["seed"],
               "truth": truth["parameters"], "derived": derived,
               "saturation": truth["saturation"], "elapsed_s": elapsed,
               "warnings": truth["warnings"]}
    p = truth["parameters"]
    lines = [
        (f"EMA bench: {truth['n_samples']} samples at {truth['rig']['f_ctrl']:g} Hz "
         f"({args.duration:g} s), sweep ±{1e3 * args.sweep:g} mm with a ±{1e3 * args.amplitude:g}"
         f" mm multisine to {args.fmax:g} Hz, seed {args.seed}, simulated in {elapsed:.2f} s"),
        (f"truth: K_m = {p['K_m']:.4g} N·m/A, J_total = {p['J_total']:.4g} kg·m², k_s = "
         f"{p['k_s']:.4g} N/m, m_L = {p['m_L']:.4g} kg; screw mode "
         f"{derived['resonance_hz']:.3g} Hz"),
        *(f"warning: {w}" for w in truth["warnings"]),
        "written: " + ", ".join(str(f) for f in files),
    ]
    return payload, "\n".join(lines)


def _run_fleet(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..._progress import stage
    from ...cli._flags import at_least, finite, folder_out, in_flags, positive
    from ._fleet import write_fleet

    at_least("--units", args.units, 3)
    at_least("--bad-every", args.bad_every, 0)
    at_least("--corrupt", args.corrupt, 0)
    at_least("--seed", args.seed, 0)
    finite("--drift", args.drift, "per 100 days")
    positive("--duration", args.duration, "s")
    folder_out("--out", args.out)
    with in_flags(_WORDS), stage(f"simulating {args.units + args.corrupt} EMA units"):
        fleet = write_fleet(args.out, units=args.units, seed=args.seed,
                            bad_every=args.bad_every, corrupt=args.corrupt, drift=args.drift,
                            duration=args.duration, overwrite=args.overwrite)
    payload = {"folder": str(fleet.folder), "fleet_file": str(fleet.fleet_file),
               "manifest": str(fleet.manifest), "truth": str(fleet.truth_file),
               "bad": list(fleet.bad), "corrupt": list(fleet.corrupt)}
    text = (f"virtual EMA fleet: {args.units + args.corrupt} records in {fleet.folder}\n"
            f"  out of tolerance: {', '.join(fleet.bad) or 'none'}\n"
            f"  corrupt files:    {', '.join(fleet.corrupt) or 'none'}\n"
            f"  truth:            {fleet.truth_file}\n"
            f"next: servoid fleet {fleet.fleet_file}")
    return payload, text
