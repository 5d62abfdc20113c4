"""Slow statistical studies, run as pytest subprocesses (full run only).

Cases
-----
one-step CI calibration, 200 runs
    ``tests/closedloop/test_closedloop_onestep.py::test_ci_calibration_200_runs``
    (``@pytest.mark.slow``, deselected by the default test run): 200
    independent 30 dB output-noise records of the spec-§4 closed loop (first
    half of the PRBS record, 10 235 samples each), one ``fit_one_step`` from
    (2000, 100, 0.5) per record, and the fraction of 95 % confidence
    intervals of ω_hp that contain the truth. It passes when the coverage
    lies in [0.90, 0.99] (Binomial(200, 0.95): false-alarm rate ≈ 0.16 %).

Method
------
``python -m pytest -m slow -q <test id>`` in a subprocess from the
repository root; ``median_ms`` = ``best_ms`` = the subprocess's wall time
(interpreter start-up, collection and imports included), with pytest's own
duration, the outcome and the coverage in ``extra``: the coverage the test
prints (passing or failing), or on failure the assertion message. Skipped under ``--quick`` (it takes several seconds to minutes).
"""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

from _harness import Result

SUITE = "studies"
ROOT = Path(__file__).resolve().parent.parent
STUDIES = (
    (
        "one-step CI calibration, 200 runs",
        "tests/closedloop/test_closedloop_onestep.py::test_ci_calibration_200_runs",
        200 * 10235,
    ),
)


def _coverage(text: str) -> float | None:
    """The coverage the study printed (passing: ``... 200 runs: 0.955``; failing: the assertion)."""
    for pattern in (r"over 200 runs: (0?\.\d+|1\.000)\b", r"AssertionError: (0?\.\d+|1\.0)\b",
                    r"coverage\s*=\s*(0?\.\d+|1\.0)\b"):
        m = re.search(pattern, text)
        if m:
            return float(m.group(1))
    return None


def run(quick: bool = False) -> list[Result]:
    """Run each study once; nothing under ``quick``."""
    if quick:
        print("# studies: skipped under --quick", file=sys.stderr)
        return []
    rows = []
    for case, test_id, samples in STUDIES:
        cmd = [sys.executable, "-m", "pytest", "-m", "slow", "-q", "-s", "-p", "no:cacheprovider",
               "--tb=short", "--showlocals", test_id]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
        wall = time.perf_counter() - t0
        text = proc.stdout + proc.stderr
        summary = next((ln for ln in reversed(text.splitlines()) if " in " in ln
                        and any(w in ln for w in ("passed", "failed", "error", "deselected"))), "")
        m = re.search(r"in ([\d.]+)s", summary)
        passed = proc.returncode == 0 and "1 passed" in summary
        outcome = "passed" if passed else ("failed" if "failed" in summary else
                                           f"exit {proc.returncode}")
        coverage = _coverage(text)
        note = outcome + ("" if coverage is None else f", coverage {coverage:.3f}")
        if passed and coverage is None:
            note += " (coverage within [0.90, 0.99]; the test prints no number)"
        row = Result(SUITE, case, samples, "pytest -m slow (subprocess wall)", wall * 1e3,
                     wall * 1e3, 1, solver=outcome, note=note)
        row.extra.update({
            "command": " ".join(cmd[1:]),
            "returncode": proc.returncode,
            "passed": passed,
            "coverage": coverage,
            "pytest_summary": summary.strip(" ="),
            "pytest_seconds": float(m.group(1)) if m else None,
        })
        if not passed:
            row.extra["output_tail"] = text[-3000:]
        rows.append(row)
    return rows


if __name__ == "__main__":
    from _harness import format_table

    print(format_table(run(quick=False)))
