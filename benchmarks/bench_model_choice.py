"""Model choice (issue 25): ``method = "auto"`` time, its picks, and the higher-order tests' level.

Cases
-----
auto-1e4
    ``identify()`` with ``[identify] method = "auto"`` (the default candidate
    set, one hold-out of 30 %) on a 1e4-sample record of a Wiener plant (a
    continuous second-order plant simulated far above the rate by
    ``servoid.bench.simulate_lti``, then tanh, AR(1) coloured noise), on
    ``workers = 2``; a validation record of the same length. One timed call
    (the choice is a single run); ``extra`` holds each candidate's fit time on
    the folds and its held-out score, so the leaderboard's times are here.
picks
    ``auto`` on 20 seeds (2 under ``--quick``) of each generator family —
    linear (the plant alone), ARX (an ARX(2, 2) with a lightly damped pair,
    its noise through 1/A: the structure ARX fits), Wiener (tanh after the
    plant), Hammerstein (u + 0.5·u² before it) and NARX (a discrete NARX
    with a y·u cross term, which no block model has) — 3000-sample records
    with AR(1) noise (ARX: white through 1/A): the share of seeds whose
    chosen candidate is of the true family (linear and ARX: a linear method;
    Wiener: a Wiener model; Hammerstein: a Hammerstein model or NARX; NARX:
    NARX), the share within 2 fit points of the best candidate on the
    validation record, and which test opened ``auto``'s gate to the
    nonlinear families.  And the refit gaps (``refit_gap``): per seed the
    chosen candidate's gap and whether the run was flagged (``rankable``
    false: its |gap| beyond ``REFIT_TOLERANCE``), the false flags (a choice
    of the true family flagged), and over every candidate the 95th
    percentile and largest |gap| per method and the share of its gaps beyond
    the tolerance (how often it would be flagged were it chosen).
level / power
    ``nonlinearity_tests`` on the residuals of the true linear model with
    AR(1)-coloured noise (200 seeds: the false-alarm rate at the 1 % level)
    and of an FIR least-squares fit to a Wiener and a Hammerstein plant (200
    seeds each: the detection rate), N = 2000.
output-power
    The gate's output-power test (``servoid.workflows._gate``) on the
    same 3000-sample generator as the picks: the true linear model's
    residuals (200 seeds: false alarms at 1 %) and the best linear
    approximation's residuals of the Wiener plant (200 seeds: detections).
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np
from _harness import Result
from scipy.signal import lfilter

from servoid.bench import simulate_lti
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.models import TransferFunction
from servoid.validate import nonlinearity_tests
from servoid.workflows import identify
from servoid.workflows._choice import REFIT_TOLERANCE
from servoid.workflows._gate import output_power_pvalue

SUITE = "model-choice"
DT = 0.01
WN = 2 * np.pi * 2.0
PLANT = TransferFunction([WN**2], [1.0, 2 * 0.5 * WN, WN**2])
FAMILY = {"linear": {"arx", "oe", "bj", "tf", "n4sid"}, "arx": {"arx", "oe", "bj", "tf", "n4sid"},
          "wiener": {"wiener"},
          "hammerstein": {"hammerstein", "narx"}, "narx": {"narx"}}


def _record(kind: str, n: int, seed: int) -> Experiment:
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.standard_normal(n // 2), 2)
    if kind == "arx":  # ARX(2, 2) itself: a lightly damped pair, the noise through 1/A
        a = np.poly([0.97 * np.exp(1j * 0.3), 0.97 * np.exp(-1j * 0.3)]).real
        y = lfilter([0.0, 0.05, 0.03], a, u) + lfilter([1.0], a, 0.02 * rng.standard_normal(n))
        return Experiment.from_arrays(DT, u=u, y=y)
    if kind == "narx":
        y = np.zeros(n)
        for t in range(2, n):
            y[t] = (1.2 * y[t - 1] - 0.5 * y[t - 2] + 0.3 * u[t - 1] + 0.15 * u[t - 2]
                    + 0.1 * y[t - 1] * u[t - 1])
        y = y + lfilter([1.0], [1.0, -0.9], 0.01 * rng.standard_normal(n))
        return Experiment.from_arrays(DT, u=u, y=y)
    w = u + 0.5 * u**2 if kind == "hammerstein" else u
    x = simulate_lti(PLANT, w, DT, rng=seed)["y"]
    y = np.tanh(1.2 * x) if kind == "wiener" else x
    y = y + lfilter([1.0], [1.0, -0.9], 0.01 * rng.standard_normal(u.size))
    return Experiment.from_arrays(DT, u=u, y=y)


def _auto(folder: Path, kind: str, n: int, seed: int, workers: int = 1) -> tuple[object, float]:
    write_csv(_record(kind, n, seed), folder / "est.csv", overwrite=True)
    write_csv(_record(kind, n, seed + 10_000), folder / "val.csv", overwrite=True)
    path = folder / "auto.toml"
    write_experiment_spec({"data": {"file": "est.csv"},
                           "channels": {"u": {"source": "u", "role": "u"},
                                        "y": {"source": "y", "role": "y"}},
                           "validation": {"file": "val.csv"},
                           "identify": {"method": "auto", "workers": workers}}, path,
                          overwrite=True)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = identify(path, write=False)
    return result, time.perf_counter() - start


def _gap(value: float) -> float | None:
    return round(float(value), 2) if np.isfinite(value) else None


def _picks(folder: Path, kind: str, seeds: int) -> Result:
    """``auto`` on `seeds` records of one family: its picks and the refit gaps."""
    right = near = flagged = false_flags = 0
    chosen, gates, runs = [], [], []
    gaps: dict[str, list[float]] = {}  # every admissible candidate's gap, by method
    for seed in range(seeds):
        res, _ = _auto(folder, kind, 3000, 100 + seed)
        entry = next(e for e in res.entries if e.label == res.label)  # type: ignore[attr-defined]
        chosen.append(res.label)  # type: ignore[attr-defined]
        gate = res.gate  # type: ignore[attr-defined]
        gates.append("closed" if "no nonlinear family" in gate else
                     "output-power" if "output-power" in gate else "higher-order")
        true = entry.score.candidate.method in FAMILY[kind]
        right += true
        flagged += not res.rankable  # type: ignore[attr-defined]
        false_flags += true and not res.rankable  # type: ignore[attr-defined]
        fits = [e.validation.fit_percent for e in res.entries  # type: ignore[attr-defined]
                if e.validation is not None]
        near += entry.validation.fit_percent > max(fits) - 2.0
        for e in res.entries:  # type: ignore[attr-defined]
            if np.isfinite(e.refit_gap):
                gaps.setdefault(e.score.candidate.method, []).append(float(e.refit_gap))
        runs.append({"seed": 100 + seed, "chosen": res.label,  # type: ignore[attr-defined]
                     "true_family": bool(true), "chosen_gap": _gap(entry.refit_gap),
                     "rankable": bool(res.rankable),  # type: ignore[attr-defined]
                     "gaps": {e.label: _gap(e.refit_gap)
                              for e in res.entries}})  # type: ignore[attr-defined]
    every = np.abs(np.concatenate([np.asarray(v) for v in gaps.values()])) if gaps else \
        np.array([np.nan])
    p95 = {m: round(float(np.percentile(np.abs(v), 95)), 2) for m, v in sorted(gaps.items())}
    worst = {m: round(float(np.max(np.abs(v))), 2) for m, v in sorted(gaps.items())}
    over = {m: round(float(np.mean(np.abs(v) > REFIT_TOLERANCE)), 3)
            for m, v in sorted(gaps.items())}  # would be flagged if chosen
    chosen_abs = [abs(r["chosen_gap"]) for r in runs if r["chosen_gap"] is not None]
    return Result(SUITE, f"picks-{kind}", 3000, "auto", float("nan"), float("nan"), seeds,
                  note=(f"true family {right}/{seeds}, within 2 points {near}/{seeds}, "
                        f"flagged {flagged}/{seeds} (true family flagged {false_flags}); "
                        f"|refit gap| of all candidates: 95th percentile "
                        f"{np.percentile(every, 95):.2f}, max {np.max(every):.2f}"),
                  extra={"true_family": right / seeds, "within_2": near / seeds,
                         "flagged": flagged / seeds, "false_flags": false_flags / seeds,
                         "chosen_gap_abs_max": round(max(chosen_abs), 2) if chosen_abs else None,
                         "gap_abs_p95": round(float(np.percentile(every, 95)), 2),
                         "gap_abs_max": round(float(np.max(every)), 2),
                         "gap_abs_p95_by_method": p95, "gap_abs_max_by_method": worst,
                         "over_tolerance_by_method": over,
                         "chosen": chosen, "gate": gates, "runs": runs})


def _linear_residual(seed: int, kind: str, n: int = 2000) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    noise = lfilter([1.0, 0.5], [1.0, -0.8], 0.05 * rng.standard_normal(n))
    if kind == "linear":
        return noise, u  # the true model's residuals
    if kind == "wiener":
        y = np.tanh(1.5 * lfilter([0.0, 0.3], [1.0, -0.7], u))
    else:
        y = lfilter([0.0, 0.3], [1.0, -0.7], u + 0.5 * u**2)
    y = y + noise
    lags = np.column_stack([np.ones(n), *(np.roll(u, k) for k in range(1, 25))])[25:]
    theta = np.linalg.lstsq(lags, y[25:], rcond=None)[0]
    return y[25:] - lags @ theta, u[25:]


def _power_residual(seed: int, kind: str, n: int = 3000) -> tuple[np.ndarray, ...]:
    """(residuals, simulated output, input) of the true linear model, or of the best linear
    approximation of the Wiener plant, on the picks' generator."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.standard_normal(n // 2), 2)
    x = simulate_lti(PLANT, u, DT, rng=seed)["y"]
    noise = lfilter([1.0], [1.0, -0.9], 0.01 * rng.standard_normal(u.size))
    if kind == "linear":
        return noise, x, u
    y = np.tanh(1.2 * x) + noise
    yhat = np.polyval(np.polyfit(x, y, 1), x)
    return y - yhat, yhat, u


def run(quick: bool = False) -> list[Result]:
    out: list[Result] = []
    n_big = 2000 if quick else 10_000
    seeds = 2 if quick else 20
    tests = 20 if quick else 200
    with TemporaryDirectory() as tmp:
        folder = Path(tmp)
        result, seconds = _auto(folder, "wiener", n_big, 1, workers=2)
        per = {e.label: {"fit_s": round(e.score.seconds, 3),
                         "held_out": None if not np.isfinite(e.score.mean) else
                         round(e.score.mean, 2), "status": e.score.status}
               for e in result.entries}  # type: ignore[attr-defined]
        out.append(Result(SUITE, f"auto-{n_big:g}", n_big, "identify(method = \"auto\")",
                          seconds * 1e3, seconds * 1e3, 1,
                          note=f"chosen {result.label}; {len(per)} candidates, workers = 2",  # type: ignore[attr-defined]
                          extra={"candidates": per}))
        for kind in ("linear", "arx", "wiener", "hammerstein", "narx"):
            out.append(_picks(folder, kind, seeds))
    for kind in ("linear", "wiener", "hammerstein"):
        start = time.perf_counter()
        hits = sum(nonlinearity_tests(*_linear_residual(s, kind)).detected for s in range(tests))
        ms = (time.perf_counter() - start) * 1e3 / tests
        what = "false alarms" if kind == "linear" else "detections"
        out.append(Result(SUITE, f"{'level' if kind == 'linear' else 'power'}-{kind}", 2000,
                          "nonlinearity_tests", ms, ms, tests,
                          note=f"{what} {hits}/{tests} at the 1 % level",
                          extra={"rate": hits / tests}))
    for kind in ("linear", "wiener"):
        start = time.perf_counter()
        hits = sum(output_power_pvalue(*_power_residual(s, kind)) < 0.01 for s in range(tests))
        ms = (time.perf_counter() - start) * 1e3 / tests
        what = "false alarms" if kind == "linear" else "detections"
        out.append(Result(SUITE, f"output-power-{kind}", 3000, "output_power_pvalue", ms, ms,
                          tests, note=f"{what} {hits}/{tests} at the 1 % level",
                          extra={"rate": hits / tests}))
    return out


if __name__ == "__main__":
    import sys

    for r in run("--quick" in sys.argv):
        print(f"{r.case:<20} {r.median_ms:10.1f} ms  {r.note}")
