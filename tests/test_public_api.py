"""The curated public surface: exports pinned, every export documented."""

from __future__ import annotations

import importlib
import inspect

import pytest

PACKAGES = ["servoid", "servoid.data", "servoid.signals", "servoid.models", "servoid.estimate",
            "servoid.validate", "servoid.report", "servoid.workflows", "servoid.cli",
            "servoid.actuators", "servoid.closedloop", "servoid.bench", "servoid.datasets",
            "servoid.multistep"]


PINNED = {
    "servoid": [
        "ChannelError", "ConvergenceError", "DataError", "Experiment", "ExperimentSet",
        "FileFormatError", "IdentifiabilityError", "ModelError", "OptionError", "OptionTypeError",
        "OutputExistsError", "ServoidError", "ServoidWarning", "__version__",
    ],
    "servoid.estimate": [
        "FRICTION_MODELS", "ArxOrders", "Estimate", "FilteredSignal", "GreyboxModel",
        "GreyboxParameter", "InverseDynamicsRegression", "LeastSquaresResult", "OrderCandidate",
        "OrderSelection", "ParameterRow", "RecursiveLeastSquaresResult", "filter_product",
        "fit_arx", "fit_closed_loop_oe", "fit_greybox", "fit_inverse_dynamics", "fit_rls",
        "fit_separable", "fit_tf_greybox", "inverse_dynamics_regression", "lstsq",
        "select_arx_order", "solve_gram", "state_variable_filter",
    ],
    "servoid.validate": [
        "ResidualAnalysis", "ValidationReport", "fit_percent", "nrmse", "relative_error",
        "residual_analysis", "rmse", "simulate_from_data", "vaf", "validate",
    ],
    "servoid.report": [
        "Figure", "Page", "Section", "Table", "new_figure", "plot_bode", "plot_force_fit",
        "plot_friction", "plot_linear", "plot_loop", "plot_poles", "plot_residuals",
        "plot_validation", "render_html", "save_figure", "to_jsonable", "write_html",
        "write_json",
    ],
    "servoid.workflows": [
        "ClosedLoopIdentification", "DemoResult", "IdentificationResult",
        "InverseDynamicsIdentification", "PneumaticIdentification", "controller_from_table",
        "identify", "identify_closed_loop_spec", "identify_inverse_dynamics_spec",
        "identify_pneumatic_spec", "loop_from_table", "run_demo",
    ],
    "servoid.cli": [
        "main",
    ],
    "servoid.datasets": [
        "emps_path", "load_emps",
    ],
    "servoid.multistep": [
        "DERIVATIVES", "EDGES", "MDOT_LIMIT", "RECORDS", "REFINABLE", "KnownConstants",
        "MultistepResult", "RecordComparison", "RefinementResult", "StepResult", "compare_record",
        "estimate_controller", "identify_critical_pressure", "identify_critical_velocity",
        "identify_flow", "identify_low_speed_friction", "identify_multistep",
        "identify_sliding_friction", "identify_thermodynamics", "identify_valve",
        "refine_parameters", "simulate_record", "zero_phase_derivatives",
    ],
}
# actuators, closedloop, bench, data, models and signals pin theirs in their own test folders


@pytest.mark.parametrize("name", sorted(PINNED))
def test_exports_are_pinned(name):
    assert importlib.import_module(name).__all__ == PINNED[name]


def test_top_level_exports():
    import servoid

    assert servoid.__all__ == sorted(servoid.__all__, key=str.lower) or servoid.__all__ == sorted(
        servoid.__all__
    )
    assert {"Experiment", "ExperimentSet", "ServoidError", "DataError", "__version__"} <= set(
        servoid.__all__
    )


@pytest.mark.parametrize("name", PACKAGES)
def test_all_names_exist_and_are_documented(name):
    module = importlib.import_module(name)
    assert module.__doc__, f"{name} has no module docstring"
    for export in module.__all__:
        obj = getattr(module, export)
        if inspect.isfunction(obj) or inspect.isclass(obj):
            doc = inspect.getdoc(obj)
            assert doc, f"{name}.{export} has no docstring"
            summary = doc.splitlines()[0]
            assert len(summary) < 64, f"{name}.{export}: summary too long: {summary!r}"  # STYLE §5
            assert summary.endswith("."), f"{name}.{export}: summary must end with a period"


def test_error_tree():
    import servoid

    assert issubclass(servoid.DataError, ValueError)
    assert issubclass(servoid.FileFormatError, servoid.DataError)
    assert issubclass(servoid.ChannelError, KeyError)
    assert issubclass(servoid.ConvergenceError, RuntimeError)
    assert issubclass(servoid.OutputExistsError, FileExistsError)
    assert issubclass(servoid.OptionTypeError, TypeError)
    for cls in (servoid.DataError, servoid.OptionError, servoid.OptionTypeError,
                servoid.ModelError):
        assert issubclass(cls, servoid.ServoidError)
