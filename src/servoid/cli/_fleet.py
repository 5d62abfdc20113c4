"""``servoid fleet`` and ``servoid bench fleet``: a batch or a life test of many records."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ._flags import at_least, finite, folder_out, out_path

__all__ = ["add_bench_fleet", "add_fleet"]


def add_fleet(commands: Any, json_flag: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``servoid fleet``."""
    fleet = commands.add_parser(
        "fleet", help="identify every record of a production batch or a life test",
        description="Identify every record a fleet file names (a manifest CSV/Parquet or a "
        "glob of experiment files) with one registered method, check acceptance limits (a "
        "unit passes only when its 95 % interval lies inside), find trends, drift and "
        "outliers, and write fleet.csv, fleet.parquet, fleet.json and report.html. Records "
        "run as Dask tasks on a local cluster (one worker per core) unless --workers 1; it "
        "listens on 127.0.0.1 only, over TLS with credentials made for this run, and has "
        "no dashboard unless --dashboard. Finished records are stored and skipped when the "
        "command is run again with the same inputs (--force redoes them). See "
        "docs/fleets.md.",
    )
    fleet.add_argument("fleet", type=Path, help="fleet file (.toml)")
    fleet.add_argument("--out", type=out_path, help="results folder (default: [report] folder, "
                       "else <fleet>-results beside the fleet file)")
    fleet.add_argument("--workers", type=int, default=None,
                       help="worker processes of the local Dask cluster (default: one per "
                       "core); 1 runs the records one after another in this process")
    fleet.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="address of a running Dask scheduler: tls://host:8786 with its "
                       "TLS files (--tls-*, or Dask's configuration), or tcp://host:8786 "
                       "with --insecure")
    fleet.add_argument("--tls-ca-file", type=Path, metavar="PEM",
                       help="the scheduler's CA certificate (with --scheduler tls://...)")
    fleet.add_argument("--tls-cert", type=Path, metavar="PEM",
                       help="this client's certificate (with --scheduler tls://...)")
    fleet.add_argument("--tls-key", type=Path, metavar="PEM",
                       help="this client's private key, when not in --tls-cert")
    fleet.add_argument("--insecure", action="store_true",
                       help="accept a plain tcp:// scheduler: anyone who can reach it runs "
                       "code as you")
    fleet.add_argument("--dashboard", action="store_true",
                       help="serve the local cluster's Dask dashboard on 127.0.0.1 (8787 "
                       "when free); every user of this machine can view it")
    fleet.add_argument("--allow-duplicates", action="store_true",
                       help="accept records whose data are byte-identical copies of another's")
    fleet.add_argument("--force", action="store_true",
                       help="identify every record again, also those already done")
    fleet.add_argument("--allow-outside", action="store_true",
                       help="let [report] folder point outside the fleet file's folder")
    fleet.add_argument("--overwrite", action="store_true",
                       help="replace files in the results folder that an earlier servoid "
                       "fleet did not write there (the inputs never)")
    fleet.add_argument("--allow-code", action="store_true",
                       help="let records whose method runs Python code (method = \"greybox\") "
                       "run it; every such record is identified again on each run")
    fleet.add_argument("--quiet", action="store_true", help="no progress on stderr")
    json_flag(fleet)
    fleet.set_defaults(run=_run_fleet)


def _run_fleet(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..fleet import run_fleet

    if args.workers is not None:
        at_least("--workers", args.workers, 1)
    if args.workers is not None and args.scheduler is not None:
        from .._errors import OptionError

        raise OptionError("--workers sets the local cluster; with --scheduler the cluster's "
                          "own workers run the records: give one of them")
    tls = (args.tls_ca_file, args.tls_cert, args.tls_key)
    security = None
    if any(f is not None for f in tls):
        from ..fleet import tls_security

        if args.scheduler is None:
            from .._errors import OptionError

            raise OptionError("--tls-ca-file, --tls-cert and --tls-key are for a scheduler "
                              "given with --scheduler tls://...; the local cluster makes its "
                              "own credentials")
        security = tls_security(*tls)
    result = run_fleet(args.fleet, args.out, scheduler=args.scheduler, workers=args.workers,
                       force=args.force, allow_outside=args.allow_outside,
                       progress=not (args.quiet or args.json), overwrite=args.overwrite,
                       security=security, insecure=args.insecure, dashboard=args.dashboard,
                       verbose=bool(getattr(args, "verbose", False)),
                       allow_duplicates=args.allow_duplicates, allow_code=args.allow_code)
    if result.interrupted:
        print(str(result), file=sys.stderr)
        raise KeyboardInterrupt
    return result.to_dict() | {"files": [str(f) for f in result.files]}, str(result)


def add_bench_fleet(rigs: Any, json_flag: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``servoid bench fleet`` to the bench's rigs."""
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


def _run_bench_fleet(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..plants.ehsa import write_virtual_fleet

    at_least("--units", args.units, 3)
    at_least("--bad-every", args.bad_every, 0)
    at_least("--corrupt", args.corrupt, 0)
    at_least("--seed", args.seed, 0)
    finite("--drift", args.drift, "per 100 days")
    folder_out("--out", args.out)
    if not 5 <= args.register <= 16:
        from .._errors import DataError

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
