"""The known-answer table of docs/pnlss.md, from the tests' own generators.

Usage: ``PYTHONPATH=src python benchmarks/study_pnlss_known.py`` (about a minute).
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "nonlinear"))

from test_pnlss import _free_run_rms, _record

from servoid import ServoidWarning
from servoid.nonlinear import fit_pnlss


def main() -> None:
    warnings.simplefilter("ignore", ServoidWarning)
    cases = [("duffing", 0.005, 2, 3, "full", 100), ("duffing", 0.005, 2, 3, "state", 100),
             ("duffing", 0.005, 2, 1, "full", 100), ("wh", 0.02, 3, 3, "full", 100),
             ("wh", 0.02, 3, 3, "full", 300)]
    for kind, noise, nx, degree, mono, iters in cases:
        est = fit_pnlss(_record(kind, 1, noise), nx, degree, monomials=mono, max_iter=iters)
        rms = _free_run_rms(est.model, _record(kind, 2, noise))
        print(f"{kind:8s} n_states={nx} degree={degree} {mono:5s} max_iter={iters}: free-run "
              f"RMS {rms:.5g} = {rms / noise:.3f} σ")
    est = fit_pnlss(_record("linear", 1, 0.01), 2, 3)
    val = _record("linear", 2, 0.01)
    full, lin = est.model.contribution(val["u"], est.model.initial_state(val["y"], val["u"]))
    print(f"linear plant, degree 3: nonlinear terms' RMS contribution "
          f"{np.sqrt(np.mean((full - lin) ** 2)) / 0.01:.3f} σ; free-run RMS "
          f"{_free_run_rms(est.model, val) / 0.01:.3f} σ")


if __name__ == "__main__":
    main()
