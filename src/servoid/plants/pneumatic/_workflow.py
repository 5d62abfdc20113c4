"""Servopneumatic campaign → multi-step parameters, validation and a report.

A campaign file (an experiment TOML whose ``[data]`` is the validation
record) names one experiment file per test of the multi-step scheme
(Hahn & Piepenbrink, IFAC SYSID 1994; :mod:`servoid.multistep`)::

    [identify]
    method = "pneumatic-multistep"
    valve = "valve.toml"          # S1
    thermo = "thermo.toml"        # S2
    flow = "flow.toml"            # S0 p_krit, S3
    friction = "friction.toml"    # S0 ẋ_krit, S4, S5
    validation = "validation.toml"  # S6 (default: this file's [data])
    known = {A_I = 1.963e-3, ...}   # or the same keys in [loop]; optional
                                  # mdot_sensor_bandwidth [Hz] (the ṁ sensor's lag)
    derivatives = "svf"           # or "measured" (the v_k, a_k sensors)
    valve_u_hold = "zoh"          # or "cubic": u recorded through the anti-alias filter
    refine = false                # true, or a list of parameter names

    [loop]
    K_p = 300.0                   # controller of the closed-loop tests
    K_d = 5.0                     # (optional: reconstructed by LS if absent)

    [report]
    truth = "truth.json"
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ..._checks import as_float, as_mapping, as_str, type_error
from ..._errors import DataError, OptionError, check_option
from ..._version import __version__
from ...data import Experiment, ExperimentSpec, load_experiment_spec
from ...report import (
    Check,
    Conditions,
    Figure,
    Page,
    Section,
    Table,
    Verdict,
    new_figure,
    plain,
    save_figure,
)
from ...workflows.kit import (
    Displayed,
    FigureWriter,
    Method,
    Option,
    ParameterValue,
    RecordSummary,
    TableSchema,
    boolean,
    choice,
    count_check,
    number,
    optional,
    read_truth,
    record_conditions,
    report_options,
    summary_of,
    text,
)
from ._pipeline import STD_SOURCES, MultistepResult, identify_multistep
from ._refine import REFINABLE, RecordComparison
from ._sim import PositionController
from ._steps import KnownConstants

__all__ = ["LOOP", "METHOD", "METHODS", "PneumaticIdentification"]

_TESTS = ("valve", "thermo", "flow", "friction")
_KNOWN = tuple(f.name for f in dataclasses.fields(KnownConstants))
_LABELS = {"p_I": ("p_I", "bar", 1e-5), "p_II": ("p_II", "bar", 1e-5),
           "mdot_I": ("ṁ_I", "g/s", 1e3), "mdot_II": ("ṁ_II", "g/s", 1e3),
           "x_k": ("x_k", "mm", 1e3)}


@dataclass(frozen=True, eq=False, repr=False)
class PneumaticIdentification(Displayed):
    """A campaign's multi-step result, with the truth if known.

    Attributes
    ----------
    spec : ExperimentSpec
        The campaign file.
    result : MultistepResult
        Steps, parameters, validation (and refinement).
    sources : mapping of str to Path
        The experiment file of each test.
    truth : mapping of str to float or None
        True parameters (virtual bench), from ``[report] truth``.
    folder : Path or None
        Results folder, when written.
    files : tuple of Path
        Files written.
    conditions : tuple of Conditions
        Rate, length, excitation and band of each test record.
    data_files : mapping of str to Path
        The rig file each test's experiment file names (read at the run).
    digests : dict
        SHA-256 of the input files, each hashed once (see ``digest``).
    """

    spec: ExperimentSpec
    result: MultistepResult
    sources: Mapping[str, Path]
    truth: Mapping[str, float] | None = None
    folder: Path | None = None
    files: tuple[Path, ...] = ()
    conditions: tuple[Conditions, ...] = ()
    data_files: Mapping[str, Path] = field(default_factory=dict)
    digests: dict[str, str] = field(default_factory=dict, repr=False)

    def summary(self) -> RecordSummary:
        """Every parameter of the assembled model with σ and interval, the S6 decision."""
        rows = [ParameterValue(r["name"], r["value"], r["std"], *r["ci95"], r["unit"])
                for r in self.result.table()]
        return summary_of("pneumatic-multistep", rows, self.verdict(), notes=self.result.notes)

    def models(self) -> dict[str, Any]:
        """The assembled parameter set (refined if refined) as ``"pneumatic"``."""
        return {"pneumatic": self.result.final_parameters}

    def verdict(self) -> Verdict:
        """S6: the assembled model simulated on the held-back record, channel by channel."""
        res = self.result
        checks = []
        for label, comp in (("", res.validation), (" (refined)", res.refined_validation)):
            if comp is None:
                continue
            for ch, fit in comp.fit.items():
                name = f"S6 fit {_LABELS[ch][0]}{label}"
                if fit < 0:
                    checks.append(Check(name, f"{fit:.1f} %", "fail",
                                        "the simulated channel is further from the measurement "
                                        "than its mean value"))
                else:
                    checks.append(Check(name, f"{fit:.1f} %", "pass",
                                        f"simulated on the record {comp.record!r}, not used by "
                                        "any step"))
        checks += _noise_checks(res)
        checks.append(count_check("step warnings", res.notes,
                                  "the steps warned (listed under Notes): read them before "
                                  "accepting", "caution"))
        n = len(res.table())
        tested = (f"the servopneumatic model assembled from the steps S0–S5 ({n} parameters, "
                  "each from the test that excites it), simulated on the held-back record "
                  f"{res.validation.record!r} "
                  + ("in closed loop from its reference" if res.validation.closed_loop
                     else "from its input u")
                  + " (S6) and compared channel by channel.")
        return Verdict(tested, tuple(checks), self.conditions)

    def table(self) -> list[dict[str, Any]]:
        """Parameter rows with the truth and the relative error."""
        rows = []
        for row in self.result.table():
            true = (self.truth or {}).get(row["name"])
            rows.append({**row, "truth": true,
                         "error_percent": None if true in (None, 0) else
                         100.0 * (row["value"] - true) / true})
        return rows

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""
        return {
            "servoid_version": __version__,
            "method": "pneumatic-multistep",
            "campaign_file": str(self.spec.source) if self.spec.source else None,
            "records": {k: str(v) for k, v in self.sources.items()},
            "truth": dict(self.truth) if self.truth else None,
            "parameters": self.table(),
            **{k: v for k, v in self.result.to_dict().items() if k != "parameters"},
            "verdict": self.verdict().to_dict(),
            "summary": self.summary().to_dict(),
        }

    def inputs(self) -> tuple[Path, ...]:
        """Every file the run read: each test's experiment file and rig file."""
        out = list(self.sources.values())
        for test, path in self.sources.items():
            if path.suffix == ".toml":
                out.append(self.data_files.get(test) or _data_file(path))
        if self.spec.source:
            out.append(Path(self.spec.source))
            truth = report_options(self.spec.report).get("truth")
            if truth:
                out.append(self.spec.source.parent / truth)
        return tuple(out)

    def figures(self) -> dict[str, FigureWriter]:
        """S6 validation (and refined), the steps' fits."""
        res = self.result
        out: dict[str, FigureWriter] = {
            "validation.png": partial(_plot_comparison, res.validation,
                                      title="S6: multi-step model"),
            "steps.png": partial(_plot_steps, res),
        }
        if res.refined_validation is not None:
            out["validation_refined.png"] = partial(_plot_comparison, res.refined_validation,
                                                    title="S6: refined model")
        return out

    def page(self, files: Mapping[str, Path]) -> Page:
        """The report page."""
        return _page(self, files)

    def __str__(self) -> str:
        lines = [str(self.result)]
        if self.truth:
            errs = ", ".join(f"{r['name']} {_signed(r['error_percent'], 2)}" for r in self.table()
                             if r["error_percent"] is not None)
            lines.append(f"  error vs truth: {errs}")
        lines += ["  " + line for line in self.verdict().lines()[:1]]
        if self.folder:
            lines.append(f"  report: {self.folder / 'report.html'}")
        return "\n".join(lines)


def run(spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> PneumaticIdentification:
    """Run the multi-step scheme a campaign file describes.

    Parameters
    ----------
    spec : ExperimentSpec
        The campaign (``[identify] method = "pneumatic-multistep"``; keys
        in the module notes).
    options : mapping
        The checked ``[identify]`` options.
    truth : mapping or None
        True parameters (virtual bench); default ``[report] truth``.

    Returns
    -------
    PneumaticIdentification
        The result.

    Raises
    ------
    DataError
        A test file or a known constant is missing.
    """
    base = spec.source.parent if spec.source else spec.base_dir
    sources: dict[str, Path] = {}
    records: dict[str, Experiment] = {}
    for test in _TESTS:
        if options[test] is None:
            raise DataError(f"[identify] {test} = \"<{test}.toml>\" is needed: the experiment "
                            f"file of the {test} test")
        sources[test] = base / options[test]
    if options["validation"] is not None:
        sources["validation"] = base / options["validation"]
    own = spec.source.resolve() if spec.source else None
    for test, path in sources.items():
        if own is not None and path.resolve() == own:
            raise OptionError(f"[identify] {test} = {options[test]!r} names this campaign file "
                              f"itself; name the experiment file of the {test} test")
    data_files: dict[str, Path] = {}
    for test, path in sources.items():
        sub = load_experiment_spec(path)
        records[test] = _named(sub.load(), test)
        data_files[test] = sub.data_path
    if "validation" not in records:
        records["validation"] = _named(spec.load(), "validation")
        sources["validation"] = data_files["validation"] = spec.data_path
    loop = {k: v for k, v in options["[loop]"].items() if v is not None}
    known = _known(spec.identify, loop)
    result = identify_multistep(
        records, known,
        derivatives=options["derivatives"],
        refine=options["refine"],
        refine_record=options["refine_record"],
        controller=_controller(loop, spec.identify.get("known", {})),
        p_krit=options["p_krit"],
        v_krit=options["v_krit"],
        blend=options["blend"],
        mdot_limit=options["mdot_limit"],
        valve_u_hold=options["valve_u_hold"],
    )
    if truth is None:
        truth = _truth(spec, base)
    conditions = tuple(record_conditions(records[test], f"{test}: {data_files[test].name}")
                       for test in sources)
    return PneumaticIdentification(spec, result, sources, truth, conditions=conditions,
                                   data_files=data_files)


# -- helpers --------------------------------------------------------------------------------


def _named(exp: Experiment, name: str) -> Experiment:
    return exp if exp.name else dataclasses.replace(exp, name=name)


def _known(table: Mapping[str, Any], loop: Mapping[str, Any]) -> KnownConstants:
    inline = table.get("known")
    if inline is not None:
        inline = as_mapping("known", inline, where="[identify]")
    merged = {k: as_float(k, v, where="[loop]") for k, v in dict(loop).items() if k in _KNOWN}
    merged.update({k: as_float(k, v, where="[identify.known]")
                   for k, v in dict(inline or {}).items() if k in _KNOWN})
    return KnownConstants.from_mapping(merged)


def _refine(value: Any, where: str = "[identify]", name: str = "refine") -> bool | list[str]:
    if isinstance(value, bool):
        return value
    if isinstance(value, (list, tuple)):
        names = [as_str(f"refine[{i}]", v, where=where) for i, v in enumerate(value)]
        for item in names:
            check_option(f"{where} {name}", item, REFINABLE)
        return names
    raise type_error(name, value, "true, false or a list of parameter names", where=where)


def _controller(loop: Mapping[str, Any], inline: Any) -> PositionController | None:
    gains = {k: v for k, v in {**dict(inline or {}), **dict(loop)}.items() if k in ("K_p", "K_d")}
    if not gains:
        return None
    if set(gains) != {"K_p", "K_d"}:
        raise DataError("give both controller gains K_p [V/m] and K_d [V·s/m] in [loop], "
                        "or neither (then they are reconstructed from the records)")
    return PositionController(as_float("K_p", gains["K_p"], positive=True, where="[loop]"),
                              as_float("K_d", gains["K_d"], where="[loop]"))


def _truth(spec: ExperimentSpec, base: Path) -> dict[str, float] | None:
    name = report_options(spec.report).get("truth")
    return None if name is None else read_truth(base / name, REFINABLE)


def _plot_comparison(comp: RecordComparison, path: Path, overwrite: bool, *, title: str) -> None:
    chans = list(comp.measured)
    fig = new_figure((9, 1.9 * len(chans)))
    axes = fig.subplots(len(chans), 1, sharex=True)
    for ax, ch in zip(np.atleast_1d(axes), chans, strict=True):
        label, unit, scale = _LABELS[ch]
        ax.plot(comp.t, comp.measured[ch] * scale, color="0.2", lw=0.9, label="measured")
        ax.plot(comp.t, comp.predicted[ch] * scale, color="C1", lw=0.9,
                label=f"predicted (fit {comp.fit[ch]:.1f} %)")
        ax.set_ylabel(f"{plain(label)} [{plain(unit)}]")
        ax.legend(loc="upper right", fontsize=7)
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].set_title(plain(f"{title} on the record {comp.record!r}"))
    np.atleast_1d(axes)[-1].set_xlabel("time [s]")
    fig.tight_layout()
    save_figure(fig, path, overwrite)


def _plot_steps(res: MultistepResult, path: Path, overwrite: bool) -> None:
    fig = new_figure((12, 3.4))
    axes = fig.subplots(1, 3)
    s0 = res.steps.get("S0 p_krit")
    if s0 is not None:
        axes[0].semilogy(s0.extra["grid"], np.maximum(s0.extra["grid_rss"], 1e-300), "o-", ms=3)
        axes[0].axvline(s0["p_krit"], color="C3", lw=0.8)
        axes[0].set_title(f"S0: RSS(p_krit), minimum {s0['p_krit']:.4f}", fontsize=9)
        axes[0].set_xlabel("p_krit [-]")
        axes[0].set_ylabel("RSS of the S0 fit")
    s0v = res.steps.get("S0 ẋ_krit")
    if s0v is not None:
        axes[1].plot(s0v.extra["map_speed"], s0v.extra["map_force"], ".", ms=1.5)
        axes[1].axvline(s0v["v_krit"], color="C3", lw=0.8)
        axes[1].set_title(f"S0: friction map, ẋ_krit = {s0v['v_krit']:.4g} m/s", fontsize=9)
        axes[1].set_xlabel("|ẋ_k| [m/s]")
        axes[1].set_ylabel("F_fr·sgn ẋ_k [N]")
    s2 = res.steps["S2"]
    k_hist = np.asarray(s2.extra["rls_history_kappa"])
    axes[2].plot(k_hist, label="κ")
    axes[2].set_ylim(1.0, 2.0)
    ax2 = axes[2].twinx()
    ax2.plot(np.asarray(s2.extra["rls_history_R"]), color="C1", label="R")
    ax2.set_ylim(200, 400)
    axes[2].set_title(f"S2: RLS κ = {s2['kappa']:.4f}, R = {s2['R']:.1f}", fontsize=9)
    axes[2].set_xlabel("RLS update (decimated)")
    axes[2].set_ylabel("κ [-]")
    ax2.set_ylabel("R [J/(kg·K)]")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, overwrite)


def _page(ident: PneumaticIdentification, files: Mapping[str, Path]) -> Page:
    res = ident.result
    truth = bool(ident.truth)
    cols = ("parameter", *(("truth",) if truth else ()), "estimate", "std", "95 % CI", "unit",
            "step", *(("error",) if truth else ()))
    rows = []
    for r in ident.table():
        cells = [r["name"]]
        if truth:
            cells.append("—" if r["truth"] is None else f"{r['truth']:.6g}")
        cells += [f"{r['value']:.6g}", f"{r['std']:.3g}",
                  f"[{r['ci95'][0]:.6g}, {r['ci95'][1]:.6g}]", r["unit"], r["step"]]
        if truth:
            cells.append("—" if r["error_percent"] is None else _signed(r["error_percent"]))
        rows.append(tuple(cells))
    summary = Section(
        "Identified parameters",
        paragraphs=(
            ("Multi-step scheme of Hahn & Piepenbrink (IFAC SYSID 1994, Fig. 17): each equation "
            "group is identified from the test that excites it, earlier estimates inserted into "
            f"later equations. Derivatives of the piston motion: {res.derivatives!r}."),
            f"Every std is {STD_SOURCES}. A value given in the campaign file has none.",
        ),
        tables=(Table(cols, tuple(rows), "Assembled parameter set (known constants in the "
                      "results.json)"),),
    )
    sections = [summary]
    for step in res.steps.values():
        first, last = step.segment
        est_rows = tuple((r.name, f"{r.value:.6g}", f"{r.std:.3g}",
                          f"[{r.ci_low:.6g}, {r.ci_high:.6g}]", r.unit)
                         for r in step.estimate.table())
        sections.append(Section(
            f"{step.step}: {step.title}",
            paragraphs=(step.equation,
                        (f"Record {step.record!r}: {step.n_used} of {step.mask.size} samples used "
                        f"(first {first}, last {last}); estimator {step.method}."),
                        *step.notes),
            tables=(Table(("parameter", "estimate", "std", "95 % CI", "unit"), est_rows),),
        ))
    sections.append(Section("S0 profiles, friction map and the RLS of S2",
                            figures=(Figure.from_file(files["steps.png"], "Step diagnostics"),)))
    sections.append(_validation_section(res.validation, files["validation.png"],
                                        "S6: validation of the multi-step model"))
    if res.refinement is not None and res.refined_validation is not None:
        ref = res.refinement
        ref_rows = tuple((r.name, f"{getattr(ref.start, r.name):.6g}", f"{r.value:.6g}",
                          f"{r.std:.3g}", f"[{r.ci_low:.6g}, {r.ci_high:.6g}]", r.unit)
                         for r in ref.estimate.table())
        sections.append(Section(
            "Grey-box refinement",
            paragraphs=((f"Output error on {', '.join(ref.outputs)} of the record {ref.record!r} "
                        "with the compiled simulator, weights 1/σ per channel "
                        f"({', '.join(f'{k} {v:.3g}' for k, v in ref.noise_std.items())})."),
                        *ref.notes),
            tables=(Table(("parameter", "multi-step", "refined", "std", "95 % CI", "unit"),
                          ref_rows),),
        ))
        sections.append(_validation_section(res.refined_validation,
                                            files["validation_refined.png"],
                                            "S6: validation of the refined model"))
    if res.notes:
        sections.append(Section("Notes", paragraphs=res.notes))
    name = ident.spec.source.name if ident.spec.source else "campaign"
    return Page(
        title=f"Servopneumatic multi-step identification: {name}",
        subtitle="Parameters equation group by equation group (S0–S5), validated by simulation "
                 "(S6)",
        sections=tuple(sections),
        meta=(("servoid", __version__), ("campaign file", str(ident.spec.source or "")),
              *((f"{k} record",
                 f"{p.name} (sha256 {ident.digest(ident.data_files.get(k) or _data_file(p))[:12]}…)")
                for k, p in ident.sources.items())),
    )


def _signed(x: float, digits: int = 3) -> str:
    """A relative error [%] to ``digits`` decimals; one that rounds to zero has no sign."""
    text = f"{x:+.{digits}f}"
    return f"{f'{0.0:.{digits}f}' if float(text) == 0.0 else text} %"


def _data_file(path: Path) -> Path:
    if path.suffix == ".toml":
        return load_experiment_spec(path).data_path
    return path


def _validation_section(comp: RecordComparison, fig: Path, title: str) -> Section:
    rows = tuple((_LABELS[ch][0], f"{v:.2f} %") for ch, v in comp.fit.items())
    return Section(
        title,
        paragraphs=(
            f"The full model is simulated on the held-back record {comp.record!r} "
            + ("in closed loop from its reference" if comp.closed_loop else "from its input u")
            + " and compared with the measurement ([S2] Figs 18–19); predicted mass flows are "
              "clipped to the sensor range.",
            *comp.notes,
        ),
        tables=(Table(("channel", "fit"), rows, "fit = 100(1 − ‖y − ŷ‖/‖y − ȳ‖)"),),
        figures=(Figure.from_file(fig, "Predicted vs measured"),),
    )


def _known_table(value: Any, where: str, name: str) -> Mapping[str, Any]:
    return as_mapping(name, value, where=where)


def _value(value: Any, where: str, name: str) -> float:
    return as_float(name, value, where=where)


#: ``[loop]`` of a campaign: the controller of its closed-loop tests and known constants.
LOOP = TableSchema("loop", (
    Option("K_p", None, optional(_value),
           "position gain of the closed-loop tests [V/m]; none, with K_d: reconstructed by LS"),
    Option("K_d", None, optional(_value), "velocity gain [V·s/m] (with K_p)"),
    *(Option(name, None, optional(_value),
             f"known constant {name} (as in [identify] known; there it wins)")
      for name in _KNOWN),
), help="the controller of the closed-loop tests and the actuator's known constants")


def _example(folder: Path, seed: int = 0) -> Path:
    """A short virtual campaign (every test, 1 s each at 10 kHz) and its campaign file."""
    from ._bench_files import write_pneumatic_campaign

    files = write_pneumatic_campaign(folder, seed=seed, duration=1.0, format="csv",
                                     overwrite=True)
    return next(p for p in files if p.name == "pneumatic.toml")


METHOD = Method(
    name="pneumatic-multistep",
    summary="servopneumatic actuator, equation group by equation group (S0–S6) from a "
            "campaign of experiment files, validated on pressures and mass flows",
    options=(
        *(Option(test, None, optional(text()), f"experiment file of the {test} test")
          for test in _TESTS),
        Option("validation", None, optional(text()),
               "experiment file of the S6 validation record (default: this file's [data])"),
        Option("known", None, optional(_known_table),
               "known constants A_I, A_II, V_0I, … (or in [loop])"),
        Option("derivatives", "svf", choice(("svf", "measured")),
               "state-variable filters or the measured v_k, a_k"),
        Option("refine", False, _refine, "grey-box refinement: true, false or parameter names"),
        Option("refine_record", "thermo", choice((*_TESTS, "validation")),
               "record the refinement fits"),
        Option("p_krit", None, optional(number(positive=True)),
               "fixed critical pressure ratio (skips S0)"),
        Option("v_krit", None, optional(number(positive=True)),
               "fixed critical velocity [m/s] (skips its step)"),
        Option("blend", False, boolean(), "blend the friction regimes"),
        Option("mdot_limit", 4e-3, number(positive=True), "mass-flow sensor range [kg/s]"),
        Option("valve_u_hold", "zoh", choice(("zoh", "cubic")),
               "how the valve input is held between samples"),
    ),
    run=run,
    tables=(LOOP,),
    example=_example,
)

#: The plant's methods, as its record names them.
METHODS = (METHOD,)


#: A 95 % interval wider than this share of the value (either side) is "wide".
WIDE_INTERVAL = 0.2


def _noise_checks(res: MultistepResult) -> list[Check]:
    """The regressors' noise: the LS bias the IV removed, and intervals it left wide.

    S0, S1, S3 and S4 solve their equations by instrumental variables and
    keep the LS estimate beside (``options["ls_values"]``): the largest
    (LS − IV)/σ is how far the sensors' noise would have pulled the LS
    estimate.  Below ~30 dB the intervals that carry it widen: a parameter
    whose 95 % interval spans more than ±20 % of its value is a caution.
    """
    shifts = []
    for step in res.steps.values():
        ls = step.estimate.options.get("ls_values") or {}
        for name, value in ls.items():
            std = step.std(name)
            if std > 0.0 and np.isfinite(value):
                shifts.append(((value - step[name]) / std, name, step.step))
    checks = []
    if shifts:
        z, name, where = max(shifts, key=lambda t: abs(t[0]))
        checks.append(Check(
            "noise in the regressors (LS − IV)", f"{name} {z:+.1f}σ", "info",
            f"steps {', '.join(sorted({s for _, _, s in shifts}))} estimate by instrumental "
            "variables; least squares on the same noisy regressors (x_v, p_I, p_II, v_k) "
            f"would have put {name} ({where}) {abs(z):.1f}σ from the reported value"))
    wide = [(r["name"], 1.96 * r["std"] / abs(r["value"])) for r in res.table()
            if r["value"] != 0.0 and r["std"] > 0.0
            and 1.96 * r["std"] / abs(r["value"]) > WIDE_INTERVAL]
    if wide:
        text = ", ".join(f"{n} ±{100 * w:.0f} %" for n, w in wide)
        checks.append(Check(
            "wide intervals", text, "caution",
            f"the 95 % intervals of {', '.join(n for n, _ in wide)} span more than "
            f"±{100 * WIDE_INTERVAL:.0f} % of the value: the sensors are too noisy for these "
            "parameters (on the virtual rig p_krit passes ±20 % near 25 dB); raise the SNR of "
            "x_v and the pressures or record the test longer"))
    return checks
