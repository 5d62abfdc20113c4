"""``servoid bench pneumatic``: the servopneumatic actuator's rig command.

Only argparse at import: the command line builds its parser (and answers
``--help``) without the numerics; the bench loads when a command runs.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from typing import Any

from ..._flags import at_least, folder_out, in_flags, out_path, positive
from ..._progress import stage
from ...data import RigFormat  # the format records only: no numerics

__all__ = ["TEST_NAMES", "add_cli"]

#: The names of servoid.plants.pneumatic.PNEUMATIC_TESTS as literals (a test pins them).
TEST_NAMES = ("valve", "thermo", "flow", "friction", "validation")

_PNEUMATIC_WORDS = {"f_acq": "--facq", "snr_db": "--snr", "test": "--tests",
                    "duration": "--duration", "seed": "--seed"}
_PNEUMATIC_PHRASES = {"shorten the test or lower oversample": "shorten the test (--duration) "
                      "or lower the acquisition rate (--facq)"}


def add_cli(rigs: Any, json_flag: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``bench pneumatic`` to the bench's rigs."""
    names = TEST_NAMES
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


def _run_pneumatic(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    import json
    import warnings

    from ..._errors import DataError
    from ._bench_files import write_pneumatic_campaign

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
