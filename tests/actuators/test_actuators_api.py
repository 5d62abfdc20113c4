"""The public surface of servoid.actuators is pinned and documented."""

import inspect

from servoid import actuators

EXPECTED = [
    "PNEUMATIC_NOMINAL",
    "PNEUMATIC_STATE_NAMES",
    "SET_A",
    "SET_B",
    "SET_C",
    "STATE_NAMES",
    "CascadeController",
    "EhsaParameters",
    "EhsaResponse",
    "PaperConsistency",
    "PaperSetA",
    "PneumaticParameters",
    "PneumaticResponse",
    "PositionController",
    "ReducedEhsa",
    "RigidAxis",
    "RigidLoopResponse",
    "StabilityMargins",
    "chamber_pressure_rate",
    "closed_loop_bandwidth",
    "coulomb_friction",
    "critical_pressure_ratio",
    "default_dt_int",
    "full_order_closed_loop",
    "full_order_plant",
    "karnopp_friction",
    "loop_margins",
    "orifice_mass_flow",
    "paper_consistency",
    "pneumatic_dt_int",
    "pneumatic_rest_state",
    "psi_ellipse",
    "psi_max",
    "psi_saint_venant",
    "simulate_ehsa",
    "simulate_pneumatic",
    "simulate_rigid_loop",
    "stribeck_friction",
    "three_regime_friction",
    "viscous_friction",
]


def _isort_key(name: str) -> tuple[int, str]:
    # the project's order (ruff RUF022): CONSTANTS, then Classes, then functions
    kind = 0 if name.isupper() else 1 if name[0].isupper() else 2
    return kind, name


def test_exports_are_pinned_and_sorted() -> None:
    assert set(actuators.__all__) == set(EXPECTED)  # a public name is removed only on purpose
    assert sorted(actuators.__all__, key=_isort_key) == actuators.__all__
    for name in EXPECTED:
        assert hasattr(actuators, name)


def test_public_docstring_summaries_are_short_and_end_with_period() -> None:
    for name in actuators.__all__:
        obj = getattr(actuators, name)
        members = [obj]
        if isinstance(obj, type):
            members += [getattr(obj, k) for k in vars(obj) if not k.startswith("_")]
            members += [v for k, v in vars(obj).items() if isinstance(v, property)]
        for member in members:
            if not (callable(member) or isinstance(member, property)):
                continue
            doc = inspect.getdoc(member) or ""
            summary = doc.strip().splitlines()[0] if doc.strip() else ""
            assert summary, (name, member)
            assert len(summary) < 64 and summary.endswith("."), (name, summary)


def test_function_parameters_are_documented() -> None:
    for name in actuators.__all__:
        obj = getattr(actuators, name)
        if not inspect.isfunction(obj):
            continue
        doc = inspect.getdoc(obj) or ""
        for param in inspect.signature(obj).parameters:
            assert f"{param} :" in doc or f", {param}" in doc, (name, param)
