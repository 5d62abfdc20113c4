"""Where ``validate``'s time goes at one N, in one warm process.

The scaling suite times each call in a fresh process with glibc's mmap
threshold fixed (every call pays the zeroing of its fresh arrays); this
script shows the other view a user gets from repeated calls:

* the median of ``--calls`` warm calls of ``validate`` for ARX(2,2,1) and
  OE(2,2) on the scaling suite's records, with the default allocator, and
  the page faults per call (glibc serves some calls from fresh pages, which
  the kernel zeroes: ~3 ms for three 8 MB outputs);
* the residual sweep (``_fused_sums``) alone, on the worker thread's two
  halves and on one thread;
* with ``--profile``, the functions that take the time (cProfile, own time).

Run with ``NUMBA_NUM_THREADS=1`` for the one-thread figures of ``validate``
itself::

    .venv/bin/python benchmarks/profile_validate.py            # N = 1e6
    NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/profile_validate.py --profile
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import resource
import time
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numba
import numpy as np
from bench_scaling import _experiment, _signals


def _median_ms(call, calls: int) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """Median wall time [ms] of warm calls, and the page faults per call (fresh memory)."""
    call()
    times = []
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(calls):
        t0 = time.perf_counter()
        call()
        times.append((time.perf_counter() - t0) * 1e3)
    faults = (resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults) / calls
    return float(np.median(times)), faults


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=float, default=1e6, help="record length (default 1e6)")
    parser.add_argument("--calls", type=int, default=20, help="timed calls per case")
    parser.add_argument("--profile", action="store_true", help="cProfile the validate calls")
    parser.add_argument("--case", choices=("ARX", "OE"), default=None,
                        help="one case only (glibc then reuses the freed outputs: no faults)")
    args = parser.parse_args()
    n = int(args.n)

    import servoid.estimate as est
    from servoid.validate import _residuals as res
    from servoid.validate import validate

    u, y_arx, y_oe = _signals(n)
    arx, oe = _experiment(u, y_arx, "arx"), _experiment(u, y_oe, "oe")
    cases = {}
    if args.case in (None, "ARX"):
        cases["ARX(2,2,1)"] = (est.fit_arx(arx, 2, 2, 1), arx)
    if args.case in (None, "OE"):
        cases["OE(2,2)"] = (est.fit_oe(oe, 2, 2, 1), oe)
    print(f"N = {n:.0e}, NUMBA_NUM_THREADS = {numba.config.NUMBA_NUM_THREADS}, "
          f"load {os.getloadavg()[0]:.2f}")
    warnings.simplefilter("ignore")
    for label, (model, exp) in cases.items():
        ms, faults = _median_ms(lambda m=model, e=exp: validate(m, e), args.calls)
        print(f"validate {label:11s}       {ms:7.2f} ms  ({faults:.0f} page faults per call)")
    rng = np.random.default_rng(0)
    e = res._Centred.of(rng.standard_normal(n), 0.0)
    x = res._Centred.of(rng.standard_normal(n), 0.0)
    sweep = lambda: res._fused_sums(e, x, 25)
    print(f"residual sweep (M = 25)   {_median_ms(sweep, args.calls)[0]:7.2f} ms  "
          f"({'two halves on two threads' if res._worker() else 'one thread'})")
    single = lambda: res._fused_kernel(e.raw, 0.0, e.scale, x.raw, 0.0, x.scale, 25,
                                       res.BLOCK, 0, n)
    print(f"residual sweep, one call  {_median_ms(single, args.calls)[0]:7.2f} ms  (one thread)")
    if args.profile:
        for label, (model, exp) in cases.items():
            prof = cProfile.Profile()
            prof.enable()
            for _ in range(args.calls):
                validate(model, exp)
            prof.disable()
            print(f"\n{label}: own time of {args.calls} calls")
            pstats.Stats(prof).sort_stats("tottime").print_stats(8)


if __name__ == "__main__":
    main()
