"""``servoid bench ehsa|pneumatic|fleet|ema|ema-fleet``: rehearse tests on a virtual rig or a fleet."""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from typing import Any

from .._progress import stage
from ..data import RigFormat  # the format records only: no numerics
from ._flags import at_least, finite, folder_out, in_flags, out_path, positive

__all__ = ["BENCH_FIDELITIES", "PNEUMATIC_TEST_NAMES", "add_bench"]

#: servoid.plants.ehsa.FIDELITIES and the names of servoid.plants.pneumatic.PNEUMATIC_TESTS (a test pins them)
BENCH_FIDELITIES = ("reduced", "full", "nonlinear")
PNEUMATIC_TEST_NAMES = ("valve", "thermo", "flow", "friction", "validation")

_SETS = ("B", "C")
# the bench's parameters → the flags that set them, for its error messages
_EHSA_WORDS = {"f_acq": "--facq", "f_s": "--fs", "rng seed": "--seed", "snr_db": "--snr",
               "register length n": "--register/-n", "amplitude": "--amplitude",
               "bits": "--bits", "periods": "--periods", "clock": "--clock"}
_EHSA_PHRASES = {"lower the amplitude (or the offset)": "lower the amplitude (--amplitude)",
                 "raise max_samples (--max-samples)": "raise --max-samples",
                 "(a shorter register, fewer periods or fewer samples per bit)":
                 "(a shorter --register/-n, fewer --periods or a lower --clock)"}
_PNEUMATIC_WORDS = {"f_acq": "--facq", "snr_db": "--snr", "test": "--tests",
                    "duration": "--duration", "seed": "--seed"}
_PNEUMATIC_PHRASES = {"shorten the test or lower oversample": "shorten the test (--duration) "
                      "or lower the acquisition rate (--facq)"}


def add_bench(commands: Any, json_flag: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``bench ehsa`` and ``bench pneumatic`` to the sub-command set."""
    # the bench's names as literals: building the parser must not import the bench (fast --help)
    FIDELITIES = BENCH_FIDELITIES

    bench = commands.add_parser(
        "bench", help="rehearse a test on a virtual rig and write its files",
        description="Run a designed excitation on a virtual test rig (actuator in its loop, "
        "sensors, noise, anti-alias filter, ADC) and write what a real rig writes: the rig "
        "file in volts, the experiment TOML and truth.json.",
    )
    rigs = bench.add_subparsers(title="rigs", metavar="RIG", required=True)
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
    ehsa.add_argument("--amplitude", type=float, default=1e-3,
                      help="PRBS amplitude, commanded position [m] (default: %(default)s)")
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
    _add_pneumatic(rigs, json_flag)
    from ..plants.ema._cli import add_cli as add_ema  # argparse only: --help stays light

    add_ema(rigs, json_flag)


def _run_ehsa(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    import warnings

    from .._errors import DataError, check_option
    from ..plants.ehsa import FIDELITIES, SET_B, SET_C, EhsaBench, run, write_bench_files
    from ..signals import prbs

    check_option("--fidelity", args.fidelity, FIDELITIES)
    if args.clock < 1:
        raise DataError(f"--clock must be >= 1 sample per bit at --fs: a PRBS clock cannot be "
                        f"faster than the sample rate, got {args.clock}")
    if not math.isfinite(args.snr):
        raise DataError(f"--snr must be a finite number of dB, got {args.snr}")
    positive("--fs", args.fs, "Hz")
    if args.facq is not None:
        positive("--facq", args.facq, "Hz")
    finite("--amplitude", args.amplitude, "m")
    at_least("--seed", args.seed, 0)
    at_least("--max-samples", args.max_samples, 1)
    folder_out("--out", args.out)
    params = SET_B if args.set == "B" else SET_C
    f_acq = 5.0 * args.fs if args.facq is None else args.facq
    with in_flags(_EHSA_WORDS, _EHSA_PHRASES):
        bench = EhsaBench(params=params, fidelity=args.fidelity, f_acq=f_acq, f_s=args.fs,
                          bits=args.bits, snr_db=args.snr, reference=args.reference)
        ex = prbs(args.register, clock=args.clock, amplitude=args.amplitude,
                  periods=args.periods, dt=bench.dt, max_samples=args.max_samples)
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


def _add_pneumatic(rigs: Any, json_flag: Callable[[argparse.ArgumentParser], None]) -> None:
    names = PNEUMATIC_TEST_NAMES
    pn = rigs.add_parser(
        "pneumatic", help="servopneumatic actuator, multi-step campaign (models-spec §2, §3.9)",
        description="Run the test records of the multi-step identification (valve: "
        "rectangular u open loop; thermo: sine x_ref closed loop with a rectangular force; "
        "flow: sine x_ref, |mdot| <= 4 g/s; friction: rectangular u with a weak centring "
        "loop; validation: 0.7 Hz sine with a force step) on the virtual rig: all [S2] "
        "sensors (hot-wire mass flow with 1 kHz lag, saturating at 4 g/s), a 4th-order "
        "Butterworth anti-alias filter at 0.2·facq and a 16-bit ±10 V ADC at --facq. Writes "
        "<test>.tdms|csv and <test>.toml per test, pneumatic.toml (method "
        "pneumatic-multistep) and truth.json.",
    )
    pn.add_argument("--out", type=out_path, required=True,
                    help="output folder for the rig files, TOMLs and truth.json")
    pn.add_argument("--tests", nargs="+", default=list(names), metavar="TEST",
                    help=f"tests to run, among {', '.join(names)} (default: all)")
    pn.add_argument("--snr", type=float, default=40.0,
                    help="signal-to-noise ratio of every sensor channel at --facq [dB] "
                    "(default: %(default)g)")
    pn.add_argument("--seed", type=int, default=0, help="noise seed (default: %(default)s)")
    pn.add_argument("--format", choices=RigFormat.writable(first="tdms"), default="tdms",
                    help="rig file format (default: %(default)s)")
    pn.add_argument("--duration", type=float, default=None,
                    help="record length of every test [s] (default: 2 s valve, 4 s others)")
    pn.add_argument("--facq", type=float, default=10_000.0,
                    help="acquisition rate [Hz]; below 10 kHz the spool is poorly resolved "
                    "(default: %(default)g)")
    pn.add_argument("--overwrite", action="store_true",
                    help="replace files of an earlier run in --out")
    json_flag(pn)
    pn.set_defaults(run=_run_pneumatic)

    from ._fleet import add_bench_fleet

    add_bench_fleet(rigs, json_flag)


def _run_pneumatic(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    import json
    import warnings

    from .._errors import DataError
    from ..plants.pneumatic import write_pneumatic_campaign

    if not math.isfinite(args.snr):
        raise DataError(f"--snr must be a finite number of dB, got {args.snr}")
    if args.duration is not None:
        positive("--duration", args.duration, "s")
    positive("--facq", args.facq, "Hz")
    at_least("--seed", args.seed, 0)
    folder_out("--out", args.out)
    start = time.perf_counter()
    with warnings.catch_warnings(), in_flags(_PNEUMATIC_WORDS, _PNEUMATIC_PHRASES), \
            stage("simulating the servopneumatic bench's tests"):
        warnings.simplefilter("ignore")  # kept in truth.json and printed below
        files = write_pneumatic_campaign(
            args.out, tests=args.tests, snr_db=args.snr, seed=args.seed, format=args.format,
            overwrite=args.overwrite, duration=args.duration, f_acq=args.facq)
    elapsed = time.perf_counter() - start
    truth = json.loads(files[-1].read_text(encoding="utf-8"))
    tests = {
        name: {"n_samples": t["n_samples"], "duration_s": t["duration"],
               "channels": t["channels"], "purpose": t["purpose"],
               "hot_wire_saturation": t["hot_wire_saturation"]}
        for name, t in truth["tests"].items()
    }
    payload = {
        "files": [str(f) for f in files],
        "tests": tests,
        "f_acq": truth["rig"]["f_acq"],
        "snr_db": truth["snr_db"],
        "seed": truth["seed"],
        "truth": {k: truth[k] for k in truth["identified"]},
        "known": truth["known"],
        "elapsed_s": elapsed,
        "warnings": truth["warnings"],
    }
    lines = [(f"pneumatic campaign at {payload['f_acq']:g} Hz, SNR {args.snr:g} dB, seed "
              f"{args.seed}, simulated and written in {elapsed:.2f} s")]
    for name, t in tests.items():
        sat = max(t["hot_wire_saturation"].values())
        lines.append(f"  {name:<10} {t['n_samples']} samples ({t['duration_s']:g} s), "
                     f"hot-wire saturated {100 * sat:.3g} %: {t['purpose']}")
    lines.append("truth: " + ", ".join(f"{k} = {v:.6g}" for k, v in payload["truth"].items()))
    lines += [f"warning: {w}" for w in payload["warnings"]]
    lines.append("written: " + ", ".join(str(f) for f in files))
    return payload, "\n".join(lines)
