"""``servoid bench ehsa`` and ``servoid bench fleet``: the electro-hydraulic actuator's rig commands.

Only argparse at import: the command line builds its parser (and answers
``--help``) without the numerics; the bench loads when a command runs.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..._flags import at_least, finite, folder_out, in_flags, out_path, positive
from ..._progress import stage
from ...data import RigFormat  # the format records only: no numerics

__all__ = ["FIDELITIES", "add_cli"]

#: The fidelities of servoid.plants.ehsa.FIDELITIES as literals (a test pins them): building
#: the parser must not import the bench (a fast --help).
FIDELITIES = ("reduced", "full", "nonlinear")

_SETS = ("B", "C")
# the bench's parameters → the flags that set them, for its error messages
_EHSA_WORDS = {"f_acq": "--facq", "f_s": "--fs", "rng seed": "--seed", "snr_db": "--snr",
               "register length n": "--register/-n", "amplitude": "--amplitude",
               "bits": "--bits", "periods": "--periods", "clock": "--clock"}
_EHSA_PHRASES = {"lower the amplitude (or the offset)": "lower the amplitude (--amplitude)",
                 "raise max_samples (--max-samples)": "raise --max-samples",
                 "(a shorter register, fewer periods or fewer samples per bit)":
                 "(a shorter --register/-n, fewer --periods or a lower --clock)"}


def add_cli(rigs: Any, json_flag: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``bench ehsa`` and ``bench fleet`` to the bench's rigs."""
    ehsa = rigs.add_parser(
        "ehsa", help="electro-hydraulic servo actuator (models-spec §1)",
        description="PRBS test of the EHSA with mechanical position feedback. The PRBS is "
        "designed at --fs, played by the DAQ at --facq and recorded through a 4th-order "
        "Butterworth anti-alias filter (0.2·facq) and a ±10 V ADC; the TOML decimates back "
        "to --fs and declares the rig ([rig]: the filter, and whether the reference is read "
        "back or the DAC command). Warns before the run when --fs cannot resolve the "
        "actuator's hydraulic resonance (set C needs --fs >= 5700). Prints the files, the "
        "record length, the excited band and the truth.",
    )
    ehsa.add_argument("--set", choices=_SETS, default="B",
                      help="parameter set: B loaded (1500 kg), C unloaded bench (0.5 kg) "
                      "(default: %(default)s)")
    ehsa.add_argument("--fidelity", default="reduced", metavar="{" + ",".join(FIDELITIES) + "}",
                      help="actuator model: reduced 3rd-order loop (its K, omega_hp, delta_hp "
                      "are the truth), full 8th-order linear, or nonlinear simulator "
                      "(default: %(default)s)")
    ehsa.add_argument("--register", "-n", type=int, default=11,
                      help="PRBS register length n: period 2^n - 1 bits (default: %(default)s)")
    ehsa.add_argument("--clock", type=int, default=10,
                      help="PRBS samples per bit at --fs, >= 1 (default: %(default)s)")
    ehsa.add_argument("--amplitude", type=float, default=None,
                      help="PRBS amplitude, commanded position [m] (default: the largest the "
                           "actuator can run, load pressure within 1/3 of the supply: "
                           "0.19 mm for set B, 0.52 mm for set C)")
    ehsa.add_argument("--periods", type=int, default=1,
                      help="whole PRBS periods (default: %(default)s)")
    ehsa.add_argument("--fs", type=float, default=1000.0,
                      help="identification sample rate [Hz] (default: %(default)g)")
    ehsa.add_argument("--facq", type=float, default=None,
                      help="DAQ acquisition rate [Hz], an integer multiple of --fs "
                      "(default: 5·fs)")
    ehsa.add_argument("--reference", choices=("readback", "command"), default="readback",
                      help="how the rig file logs the reference: read back through the "
                      "anti-alias filter like the position (band-limited), or the DAC command "
                      "as written (a staircase) (default: %(default)s)")
    ehsa.add_argument("--snr", type=float, default=30.0,
                      help="signal-to-noise ratio of the position at --fs [dB] "
                      "(default: %(default)g)")
    ehsa.add_argument("--bits", type=int, default=16,
                      help="ADC/DAC resolution, 8..24 (default: %(default)s)")
    ehsa.add_argument("--seed", type=int, default=0,
                      help="noise seed (default: %(default)s)")
    ehsa.add_argument("--format", choices=RigFormat.writable(first="tdms"), default="tdms",
                      help="rig file format (default: %(default)s)")
    ehsa.add_argument("--out", type=out_path, required=True,
                      help="output folder for ehsa.tdms|csv, ehsa.toml and truth.json")
    ehsa.add_argument("--overwrite", action="store_true",
                      help="replace files of an earlier run in --out")
    ehsa.add_argument("--max-samples", type=int, default=200_000_000,
                      help="refuse a longer PRBS at --fs (default: %(default)s)")
    json_flag(ehsa)
    ehsa.set_defaults(run=_run_ehsa)
    fleet = rigs.add_parser(
        "fleet", help="a virtual fleet of EHSA units (the fleet demo)",
        description="Write bench records of many EHSA units around Set B with stated "
        "manufacturing scatter (valve 1.5 %, bulk modulus 2 %, volume 1 %, leakage 8 %, "
        "1 sigma truncated at 2.5 sigma), every --bad-every-th unit outside tolerance, an "
        "optional ageing drift of the leakage and --corrupt damaged files; plus units.csv, "
        "truth.csv and fleet.toml with acceptance limits. Then: servoid fleet OUT/fleet.toml.",
    )
    fleet.add_argument("--out", type=out_path, default=Path("servoid-fleet"),
                       help="folder (default: %(default)s)")
    fleet.add_argument("--units", type=int, default=24, help="units (default: %(default)s)")
    fleet.add_argument("--bad-every", type=int, default=8,
                       help="every Nth unit is outside tolerance; 0: none (default: %(default)s)")
    fleet.add_argument("--corrupt", type=int, default=1,
                       help="extra records with a truncated rig file (default: %(default)s)")
    fleet.add_argument("--drift", type=float, default=0.0,
                       help="leakage growth per 100 days of test date, e.g. 0.5 for +50 %% "
                       "(default: %(default)s)")
    fleet.add_argument("--register", "-n", type=int, default=9,
                       help="PRBS register length of each test (default: %(default)s)")
    fleet.add_argument("--seed", type=int, default=0, help="seed (default: %(default)s)")
    fleet.add_argument("--overwrite", action="store_true", help="replace an earlier fleet's files")
    json_flag(fleet)
    fleet.set_defaults(run=_run_bench_fleet)




def _run_ehsa(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    import warnings

    from ..._errors import DataError, check_option
    from ...signals import prbs
    from . import SET_B, SET_C, EhsaBench, run, within_limits, write_bench_files

    check_option("--fidelity", args.fidelity, FIDELITIES)
    if args.clock < 1:
        raise DataError(f"--clock must be >= 1 sample per bit at --fs: a PRBS clock cannot be "
                        f"faster than the sample rate, got {args.clock}")
    if not math.isfinite(args.snr):
        raise DataError(f"--snr must be a finite number of dB, got {args.snr}")
    positive("--fs", args.fs, "Hz")
    if args.facq is not None:
        positive("--facq", args.facq, "Hz")
    if args.amplitude is not None:
        finite("--amplitude", args.amplitude, "m")
    at_least("--seed", args.seed, 0)
    at_least("--max-samples", args.max_samples, 1)
    folder_out("--out", args.out)
    params = SET_B if args.set == "B" else SET_C
    f_acq = 5.0 * args.fs if args.facq is None else args.facq
    with in_flags(_EHSA_WORDS, _EHSA_PHRASES):
        bench = EhsaBench(params=params, fidelity=args.fidelity, f_acq=f_acq, f_s=args.fs,
                          bits=args.bits, snr_db=args.snr, reference=args.reference)
        ex = prbs(args.register, clock=args.clock,
                  amplitude=1e-3 if args.amplitude is None else args.amplitude,
                  periods=args.periods, dt=bench.dt, max_samples=args.max_samples)
        if args.amplitude is None:  # the default test is one the actuator can run
            ex = within_limits(params, ex)
    unresolved = bench.resolution_note()
    if unresolved:  # now, not after a simulation that is long at the rates that resolve it
        print(f"servoid: warning: {unresolved}", file=sys.stderr)
    start = time.perf_counter()
    with warnings.catch_warnings(), in_flags(_EHSA_WORDS, _EHSA_PHRASES), \
            stage(f"simulating the {args.fidelity} EHSA bench ({ex.n_samples} samples at "
                  f"{bench.f_s:g} Hz)"):
        warnings.simplefilter("ignore")  # kept in rec.warnings and printed below
        rec = run(bench, ex, rng=args.seed)
    elapsed = time.perf_counter() - start
    files = write_bench_files(rec, args.out, format=args.format, overwrite=args.overwrite)
    truth = rec.truth
    payload = {
        "files": [str(f) for f in files],
        "set": args.set,
        "fidelity": bench.fidelity,
        "n_samples": ex.n_samples,
        "n_samples_acq": rec.raw.n_samples,
        "f_s": bench.f_s,
        "f_acq": bench.f_acq,
        "reference": bench.reference,
        "duration_s": ex.duration,
        "period_samples": ex.period,
        "band_hz": list(ex.band),
        "snr_db": bench.snr_db,
        "seed": rec.seed,
        "signal_rms_m": rec.signal_rms,
        "noise_std_m": rec.noise_std,
        "truth": {"K": truth.K, "omega_hp": truth.omega_hp, "delta_hp": truth.delta_hp,
                  "c": truth.c, "F": truth.F, "exact": truth.exact},
        "elapsed_s": elapsed,
        "warnings": list(rec.warnings),
    }
    exact = ("exact" if truth.exact
             else f"reduced-model values; data from the {bench.fidelity} model")
    lines = [
        (f"EHSA set {args.set}, {bench.fidelity} model: PRBS n={args.register}, clock "
        f"{ex.clock} samples/bit, ±{ex.amplitude * 1e3:g} mm, {args.periods} period(s)"),
        (f"record: {ex.n_samples} samples at {bench.f_s:g} Hz ({ex.duration:g} s); rig file "
        f"{rec.raw.n_samples} samples at {bench.f_acq:g} Hz, {bench.bits} bit, simulated in "
        f"{elapsed:.2f} s"),
        (f"excited band {ex.band[0]:.4g}–{ex.band[1]:.4g} Hz; SNR {bench.snr_db:g} dB at "
        f"{bench.f_s:g} Hz (signal rms {rec.signal_rms * 1e6:.4g} µm, noise "
        f"{rec.noise_std * 1e6:.3g} µm)"),
        (f"truth ({exact}): K = {truth.K:.6g} 1/s, omega_hp = {truth.omega_hp:.6g} rad/s, "
        f"delta_hp = {truth.delta_hp:.4g}, c = {truth.c:.6g}, F = {truth.F:.6g}"),
        *(f"warning: {w}" for w in rec.warnings),
        "written: " + ", ".join(str(f) for f in files),
    ]
    return payload, "\n".join(lines)


def _run_bench_fleet(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ._fleet import write_virtual_fleet

    at_least("--units", args.units, 3)
    at_least("--bad-every", args.bad_every, 0)
    at_least("--corrupt", args.corrupt, 0)
    at_least("--seed", args.seed, 0)
    finite("--drift", args.drift, "per 100 days")
    folder_out("--out", args.out)
    if not 5 <= args.register <= 16:
        from ..._errors import DataError

        raise DataError(f"--register must be from 5 to 16; got {args.register}")
    fleet = write_virtual_fleet(args.out, units=args.units, seed=args.seed, drift=args.drift,
                                bad_every=args.bad_every, corrupt=args.corrupt,
                                register=args.register, overwrite=args.overwrite)
    payload = {"folder": str(fleet.folder), "fleet_file": str(fleet.fleet_file),
               "manifest": str(fleet.manifest), "truth": str(fleet.truth_file),
               "bad": list(fleet.bad), "corrupt": list(fleet.corrupt)}
    text = (f"virtual fleet: {args.units + args.corrupt} records in {fleet.folder}\n"
            f"  outside tolerance: {', '.join(fleet.bad) or 'none'}\n"
            f"  corrupt files:     {', '.join(fleet.corrupt) or 'none'}\n"
            f"  truth:             {fleet.truth_file}\n"
            f"next: servoid fleet {fleet.fleet_file}")
    return payload, text
