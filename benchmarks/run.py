"""Run servoid's benchmarks and print a table.

Usage::

    python benchmarks/run.py                 # full run, writes benchmarks/results.json
    python benchmarks/run.py --quick         # small sizes, few repeats, no studies (CI smoke, < ~30 s)
    python benchmarks/run.py --only arx --out /tmp/r.json

Adding a benchmark: write ``benchmarks/bench_<name>.py`` with a function
``run(quick: bool) -> list[_harness.Result]`` and add it to ``SUITES`` below.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

from _harness import Result, format_markdown, format_table, machine_info

#: suite name → module in benchmarks/ exposing ``run(quick) -> list[Result]``.
SUITES: dict[str, str] = {
    "arx": "bench_arx",
    "ehsa": "bench_ehsa",
    "closedloop": "bench_closedloop",
    "closedloop-coverage": "bench_closedloop_coverage",  # 240 rig runs (~2 min; 8 under --quick)
    "ehsa-validity": "bench_ehsa_validity",  # Merritt rig: flow law, skew, data limits, OE (~25 min)
    "closedloop-any": "bench_closedloop_any",  # any-plant methods on 2e4 samples vs open-loop OE
    "pneumatic": "bench_pneumatic",
    "multistep": "bench_multistep",
    "signals": "bench_signals",
    "frf": "bench_frf",
    "demo": "bench_demo",
    "model-choice": "bench_model_choice",  # auto on 1e4 samples, 100 auto runs, 1000 tests (~25 min loaded)
    "model-choice-loop": "bench_model_choice_loop",  # auto on 2 × 20 closed-loop records (~4 min)
    "pem": "bench_pem",
    "subspace": "bench_subspace",
    "studies": "bench_studies",  # slow pytest studies; skipped under --quick
    "fuzz": "bench_fuzz",  # long reader fuzz run (72 000 inputs); skipped under --quick
    "readers": "bench_readers",  # read_csv and v7.3 read_mat of 1e6 rows (~1 min)
    "scaling": "bench_scaling",  # fresh process per (method, N), N = 1e4…1e6 (~2 min)
    "fleet": "bench_fleet",  # 1000 bench records on 1 and 2 workers (8 under --quick)
    "greybox-ode": "bench_greybox_ode",  # two-state ODE, 1e4 samples; Python path ~1 min
    "narx": "bench_narx",  # term selection, 1e5 samples × 105 candidates, vs sysidentpy FROLS
    "pnlss": "bench_pnlss",  # PNLSS fit (1e4 samples, 2 states, degree 3) and simulation
    "integrator": "bench_integrator",  # every simulator kernel through its public call
    "frequency": "bench_frequency",  # LPM of 1e6 samples, ML fit on 1e4 lines, vs numpy/scipy
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small sizes, few repeats")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="JSON output (default: benchmarks/results.json for a full run, none for --quick)",
    )
    parser.add_argument(
        "--only", action="append", choices=sorted(SUITES), help="run only this suite (repeatable)"
    )
    parser.add_argument(
        "--blas-threads",
        type=int,
        default=None,
        help="set OPENBLAS_NUM_THREADS/OMP_NUM_THREADS before numpy is imported "
        "(default: leave the BLAS's own choice)",
    )
    parser.add_argument(
        "--render",
        type=Path,
        default=None,
        metavar="JSON",
        help="print a saved results file as a Markdown table and exit",
    )
    args = parser.parse_args(argv)
    if args.render is not None:
        return render(args.render)
    if args.blas_threads is not None:
        if "numpy" in sys.modules:
            parser.error("--blas-threads must be applied before numpy is imported")
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ[var] = str(args.blas_threads)
    out = args.out if args.out is not None else (None if args.quick else HERE / "results.json")

    machine = machine_info()
    print(
        f"# {machine['date']}  {machine['cpu_model']}  {machine['logical_cpus']} CPUs  "
        f"{machine['ram_gib']} GiB  load {machine['load_average_start']}"
    )
    print(
        f"# Python {machine['python']}  numpy {machine['numpy']}  scipy {machine['scipy']}  "
        f"numba {machine['numba']}  BLAS {machine['blas'].get('blas')}"
    )

    t_start = time.perf_counter()
    results = []
    suites = {}
    for name in args.only or list(SUITES):
        t0 = time.perf_counter()
        module = importlib.import_module(SUITES[name])
        rows = module.run(quick=args.quick)
        suites[name] = {
            "seconds": round(time.perf_counter() - t0, 2),
            "description": (module.__doc__ or "").strip(),
        }
        results += rows
    elapsed = time.perf_counter() - t_start
    try:
        machine["load_average_end"] = [round(x, 2) for x in os.getloadavg()]
    except OSError:
        pass

    print(format_table(results))
    print(
        f"# {len(results)} rows in {elapsed:.1f} s; load average at end "
        f"{machine.get('load_average_end')}"
    )
    print(
        "# peak MB: tracemalloc (numpy/Python allocations only; numba and BLAS internals "
        "unseen); ΔRSS MB: growth of the resident high-water mark during one call"
    )
    print("# fit_arx times exclude Experiment creation and residuals (computed lazily)")

    if out is not None:
        payload = {
            "machine": machine,
            "quick": args.quick,
            "elapsed_s": round(elapsed, 2),
            "suites": suites,
            "results": [r.to_dict() for r in results],
        }
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(payload, indent=1, default=float) + "\n")
        print(f"# wrote {out}")
    return 0


def render(path: Path) -> int:
    """Print the results of a saved run as a Markdown table."""
    payload = json.loads(path.read_text())
    m = payload["machine"]
    print(
        f"{m['date']}, {m['cpu_model']}, {m['logical_cpus']} CPUs, {m['ram_gib']} GiB, "
        f"load {m['load_average_start']} → {m.get('load_average_end')}, "
        f"BLAS threads {m['blas'].get('OPENBLAS_NUM_THREADS', 'default')}\n"
    )
    print(format_markdown([Result(**r) for r in payload["results"]]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
