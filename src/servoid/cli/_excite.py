"""``servoid excite``: design an input and write it for the DAQ to play."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from .._flags import in_flags, out_path
from ..data import RigFormat  # the format records only: no numerics

__all__ = ["add_excite"]

_KINDS = ("prbs", "multisine", "random-multisine", "chirp")
# the signal designers' parameters → the flags that set them, for their error messages
_WORDS = {"register length n": "--register/-n", "clock": "--clock", "periods": "--periods",
          "period": "--period", "dt": "--dt", "amplitude": "--amplitude", "offset": "--offset",
          "duration": "--duration", "f0": "--f0", "f1": "--f1", "f_min": "--f-min",
          "f_max": "--f-max", "max_samples": "--max-samples", "channel name": "--channel",
          "unit": "--unit", "resolution": "--resolution", "realisations": "--realisations",
          "settling_time": "--settling-time", "test_time": "--test-time",
          "per_decade": "--per-decade", "group": "--group"}
_PHRASES = {"raise max_samples (--max-samples)": "raise --max-samples",
            "lengthen the period or widen the band": "lengthen --period or widen the band "
            "--f-min..--f-max",
            "rename it or pass time=False": "it is the CSV file's time column: choose another "
            "--channel",
            "choose another unit,": "choose another --unit,",
            "or write TDMS": "or write TDMS (--out <file>.tdms)"}


def add_excite(commands: Any, json_flag: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``excite prbs|multisine|chirp`` to the sub-command set."""
    excite = commands.add_parser(
        "excite", help="design an excitation and write it as CSV or TDMS",
        description="Design a persistently exciting input and write it for the DAQ to play. "
        "Prints its length, clock and excited band.",
    )
    kinds = excite.add_subparsers(title="signals", metavar="SIGNAL", required=True)

    prbs = kinds.add_parser("prbs", help="maximum-length PRBS from an LFSR",
                            description="Maximum-length pseudo-random binary sequence.")
    prbs.add_argument("--register", "-n", type=int, required=True,
                      help="register length n (2..31): period 2^n - 1 bits")
    prbs.add_argument("--clock", type=int, default=1, help="samples per bit (default: 1)")
    prbs.add_argument("--periods", type=int, default=1, help="whole periods (default: 1)")
    _common(prbs, json_flag)
    prbs.set_defaults(run=_run_prbs)

    ms = kinds.add_parser("multisine", help="multisine with Schroeder phases",
                          description="Periodic multisine over a frequency band.")
    ms.add_argument("--period", type=int, required=True, help="samples per period")
    ms.add_argument("--f-min", type=float, required=True, help="lowest frequency [Hz]")
    ms.add_argument("--f-max", type=float, required=True, help="highest frequency [Hz]")
    ms.add_argument("--periods", type=int, default=1, help="whole periods (default: 1)")
    ms.add_argument("--phases", choices=("schroeder", "random", "zero"), default="schroeder",
                    help="phase rule (default: schroeder)")
    ms.add_argument("--seed", type=int, default=0, help="seed for random phases (default: 0)")
    _common(ms, json_flag)
    ms.set_defaults(run=_run_multisine)

    rm = kinds.add_parser(
        "random-multisine", help="random-phase multisine test (M realisations × P periods) "
        "with its plan file", description="Random-phase multisine test for the best linear "
        "approximation: full, odd or random-odd lines (detection lines left empty), linear or "
        "log grid, M realisations × P periods after the transient periods. Writes the plan "
        "beside the file (<file>.plan.json), which servoid identify (method = \"frequency\") "
        "reads.")
    rm.add_argument("--f-min", type=float, required=True, help="lowest frequency [Hz]")
    rm.add_argument("--f-max", type=float, required=True, help="highest frequency [Hz]")
    size = rm.add_mutually_exclusive_group(required=True)
    size.add_argument("--period", type=int, help="samples per period")
    size.add_argument("--resolution", type=float, help="line spacing [Hz]")
    rm.add_argument("--lines", choices=("full", "odd", "random-odd"), default="random-odd",
                    help="excited lines (default: random-odd)")
    rm.add_argument("--grid", choices=("linear", "log"), default="linear",
                    help="line spacing (default: linear)")
    rm.add_argument("--per-decade", type=int, default=20, help="lines per decade of a log grid")
    rm.add_argument("--group", type=int, default=4,
                    help="random-odd: one line left out of each group of this many odd lines")
    rm.add_argument("--realisations", type=int, default=None,
                    help="M (default: as many as --test-time allows, else 1)")
    rm.add_argument("--periods", type=int, default=2, help="measured periods P (default: 2)")
    rm.add_argument("--settling-time", type=float, default=None,
                    help="time to settle after a new realisation [s] (default: one period)")
    rm.add_argument("--test-time", type=float, default=None, help="time for the whole test [s]")
    rm.add_argument("--crest", choices=("none", "clip"), default="clip",
                    help="crest-factor optimisation (default: clip)")
    rm.add_argument("--seed", type=int, default=0, help="seed of lines and phases (default: 0)")
    _common(rm, json_flag)
    rm.set_defaults(run=_run_random_multisine)

    ch = kinds.add_parser("chirp", help="swept sine", description="Swept sine from f0 to f1.")
    ch.add_argument("--duration", type=float, required=True, help="length [s]")
    ch.add_argument("--f0", type=float, required=True, help="start frequency [Hz]")
    ch.add_argument("--f1", type=float, required=True, help="end frequency [Hz]")
    ch.add_argument("--method", choices=("linear", "logarithmic"), default="linear",
                    help="sweep law (default: linear)")
    _common(ch, json_flag)
    ch.set_defaults(run=_run_chirp)


def _common(p: argparse.ArgumentParser, json_flag: Callable[[argparse.ArgumentParser], None]) -> None:
    p.add_argument("--dt", type=float, required=True, help="sample period of the DAQ output [s]")
    p.add_argument("--amplitude", type=float, default=1.0, help="peak amplitude (default: 1)")
    p.add_argument("--offset", type=float, default=0.0, help="operating point (default: 0)")
    p.add_argument("--channel", default="r", help="channel name in the file (default: r)")
    p.add_argument("--unit", default="V", help="unit of the channel (default: V)")
    suffixes = " or ".join(RigFormat.named(n).suffixes[0] for n in RigFormat.writable())
    p.add_argument("--out", type=out_path, required=True, help=f"output file, {suffixes}")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    p.add_argument("--plant", default=None,
                   help="check the test against this actuator's limits (a plant with limits, "
                        "e.g. ehsa; the amplitude is then its command, e.g. --unit m)")
    p.add_argument("--set", default=None, dest="parameter_set",
                   help="the plant's parameter set for --plant (default: its first)")
    p.add_argument("--max-samples", type=int, default=200_000_000,
                   help="refuse a longer signal (default: %(default)s, 1.6 GB as float64)")
    json_flag(p)


def _run_prbs(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..signals import prbs

    _check_out(args)
    with in_flags(_WORDS, _PHRASES):
        ex = prbs(args.register, clock=args.clock, amplitude=args.amplitude, offset=args.offset,
                  periods=args.periods, dt=args.dt, max_samples=args.max_samples)
    return _write(ex, args)


def _run_multisine(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..signals import multisine

    _check_out(args)
    rng = args.seed if args.phases == "random" else None
    with in_flags(_WORDS, _PHRASES):
        ex = multisine(args.period, args.dt, args.f_min, args.f_max, amplitude=args.amplitude,
                       offset=args.offset, periods=args.periods, phases=args.phases, rng=rng,
                       max_samples=args.max_samples)
    return _write(ex, args)


def _run_random_multisine(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from .._atomic import check_writable
    from ..signals import plan_multisine, random_multisine

    _check_out(args)
    plan_path = args.out.with_name(args.out.stem + ".plan.json")
    check_writable(plan_path, args.overwrite)
    with in_flags(_WORDS, _PHRASES):
        plan = plan_multisine(args.dt, args.f_min, args.f_max, period=args.period,
                              resolution=args.resolution, lines=args.lines, grid=args.grid,
                              per_decade=args.per_decade, group=args.group,
                              settling_time=args.settling_time, test_time=args.test_time,
                              realisations=args.realisations, periods=args.periods,
                              rng=args.seed)
        ex = random_multisine(plan, rng=args.seed + 1, amplitude=args.amplitude,
                              offset=args.offset, scale="peak", crest=args.crest,
                              max_samples=args.max_samples)
    info, text = _write(ex, args)
    plan.write(plan_path, overwrite=args.overwrite)
    info.update({"plan_file": str(plan_path), "realisations": plan.realisations,
                 "periods": plan.periods, "transient_periods": plan.transient_periods,
                 "period_samples": plan.period, "resolution_hz": plan.resolution,
                 "excited_lines": len(plan.excited), "detection_lines": len(plan.detection)})
    text += (f"\n{plan.realisations} realisation(s) × ({plan.transient_periods} transient + "
             f"{plan.periods} measured) periods of {plan.period} samples, "
             f"{len(plan.excited)} excited and {len(plan.detection)} detection lines "
             f"{plan.resolution:.4g} Hz apart\nplan written to {plan_path}")
    return info, text


def _run_chirp(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..signals import chirp

    _check_out(args)
    with in_flags(_WORDS, _PHRASES):
        ex = chirp(dt=args.dt, f0=args.f0, f1=args.f1, duration=args.duration,
                   amplitude=args.amplitude, offset=args.offset, method=args.method,
                   max_samples=args.max_samples)
    return _write(ex, args)


def _check_out(args: argparse.Namespace) -> None:
    """Refuse an --out the writers cannot take before designing the signal."""
    from .._atomic import check_writable
    from .._errors import OptionError

    check_writable(args.out, args.overwrite)
    fmt = RigFormat.find(args.out)
    if fmt is None or fmt.writer is None:
        writable = ", ".join(repr(n) for n in RigFormat.writable())
        raise OptionError(f"--out {args.out}: the file type comes from its extension, one of "
                          f"{writable}; got {args.out.suffix.lower().lstrip('.')!r}")


def _write(ex: Any, args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..signals import crest_factor

    planned = _plan(ex, args)  # a bad --plant or --set before anything is written
    with in_flags(_WORDS, _PHRASES):
        exp = ex.to_experiment(name=args.channel, role="r", unit=args.unit)
        RigFormat.of(args.out).write(exp, args.out, overwrite=args.overwrite)
    info = {
        "kind": ex.kind,
        "file": str(args.out),
        "n_samples": ex.n_samples,
        "dt": ex.dt,
        "duration_s": ex.duration,
        "period_samples": ex.period,
        "clock_samples": ex.clock,
        "band_hz": list(ex.band),
        "amplitude": ex.amplitude,
        "offset": ex.offset,
        "crest_factor": float(crest_factor(ex.values)),
    }
    clock = f", clock {ex.clock} samples/bit ({ex.clock * ex.dt:g} s)" if ex.clock else ""
    period = f", period {ex.period} samples" if ex.period else ""
    text = (
        f"{ex.kind}: {ex.n_samples} samples at {1 / ex.dt:g} Hz ({ex.duration:g} s){clock}{period}\n"
        f"excited band {ex.band[0]:.4g}–{ex.band[1]:.4g} Hz, amplitude ±{ex.amplitude:g} about "
        f"{ex.offset:g}, crest factor {info['crest_factor']:.3g}\n"
        f"written to {args.out}"
    )
    if planned is not None:
        name, plan = planned
        info["limits"] = {"plant": args.plant, "set": name, **plan.to_dict()}
        where = f"{args.plant} set {name}"
        text += "\n" + (f"{where}: {plan.note()}" if plan.note() else
                         f"{where}: within every limit (largest amplitude "
                         f"±{plan.largest_amplitude:.3g} {args.unit}, set by the "
                         f"{plan.rule.binding})")
    return info, text


def _plan(ex: Any, args: argparse.Namespace) -> tuple[str, Any] | None:
    """The parameter set and the planned test against --plant's limits (None: no --plant)."""
    if getattr(args, "plant", None) is None:
        return None
    from .._errors import OptionError
    from ..plants import PLANTS

    with_limits = sorted(name for name, p in PLANTS.items() if "limits" in p.parts)
    plant = PLANTS.get(args.plant)
    if plant is None or "limits" not in plant.parts:
        raise OptionError(f"--plant {args.plant!r}: the plants with limits to check are "
                          f"{', '.join(with_limits)}")
    name = args.parameter_set or next(iter(plant.load("parameters")))
    return name, plant.load("limits")(name, ex, args.unit)
