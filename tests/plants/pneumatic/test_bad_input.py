"""Bad input: each a clear error or a ServoidWarning naming the problem."""

from __future__ import annotations

import numpy as np
import pytest
from pneumatic_records import TRUTH

from servoid import (
    ChannelError,
    ConvergenceError,
    DataError,
    IdentifiabilityError,
    ModelError,
    OptionError,
    ServoidWarning,
)
from servoid.plants.pneumatic import (
    KnownConstants,
    identify_critical_pressure,
    identify_flow,
    identify_multistep,
    identify_thermodynamics,
    identify_valve,
    refine_parameters,
)


def with_channel(rec, name, values):
    return rec.replace_channels(c.with_values(values) if c.name == name else c
                                for c in rec.channels)


@pytest.mark.filterwarnings("ignore:.*mdot_II is saturated")
def test_saturated_mass_flow_most_of_the_record(clean_records, known):
    rec = clean_records["flow"]
    # a sensor with a 1 g/s range: saturated most of the time
    clipped = with_channel(rec, "mdot_I", np.clip(rec["mdot_I"], -1e-3, 1e-3))
    with pytest.warns(ServoidWarning, match=r"mdot_I is saturated .* on \d+ % of the record"):
        step = identify_flow(clipped, known, kappa=1.4, R=290.0, p_krit=0.25, mdot_limit=1e-3)
    assert any("saturated" in n for n in step.notes)
    # the unsaturated samples that remain still give the edges exactly
    assert abs(step["ad_2"] / TRUTH.ad_2 - 1) < 1e-9


def test_spool_never_negative_names_the_edges(clean_records, known):
    rec = clean_records["flow"]
    positive = with_channel(rec, "x_v", np.abs(rec["x_v"]))
    with pytest.warns(ServoidWarning,
                      match="spool never negative: edges 1 and 3 unidentifiable"):
        step = identify_flow(positive, known, kappa=1.4, R=290.0, p_krit=0.25)
    assert set(step.estimate.names) == {"ad_2", "ad_4"}
    records = dict(clean_records, flow=positive)
    with (pytest.warns(ServoidWarning),
          pytest.raises(IdentifiabilityError, match="ad_1, ad_3 not identified")):
        identify_multistep(records, known, derivatives="measured")


def test_no_edge_identifiable_is_an_error(clean_records, known):
    rec = with_channel(clean_records["flow"], "x_v", np.zeros(clean_records["flow"].n_samples))
    with pytest.raises(IdentifiabilityError, match="spool never positive: edges 2 and 4"):
        identify_critical_pressure(rec, known)


def test_negative_absolute_pressure(clean_records, known):
    rec = clean_records["thermo"]
    gauge = with_channel(rec, "p_II", rec["p_II"] - 5e5)  # gauge pressure, some < 0
    with pytest.raises(DataError, match=r"p_II must be an absolute pressure > 0 Pa"):
        identify_thermodynamics(gauge, known)


def test_bounds_excluding_the_start_name_the_parameter(clean_records):
    with pytest.raises(DataError, match=r"start value of F_haft = 85 N lies outside"):
        refine_parameters(clean_records["thermo"], TRUTH, free=["F_haft"],
                          bounds={"F_haft": (90.0, 120.0)})


def test_divergent_simulation_during_refinement(clean_records, monkeypatch):
    # The compiled simulator picks its step from the parameters and stays stable for any
    # valid set, so a divergence (a pressure leaving (0, ∞), reported as ModelError) is
    # injected: everywhere → a clear ConvergenceError, never a number.
    import servoid.plants.pneumatic._refine as refine_mod

    rec = clean_records["thermo"].slice(0, 2000)

    def diverging(params, record, controller=None):
        raise ModelError("a chamber pressure left (0, ∞) at t = 0.01 s")

    monkeypatch.setattr(refine_mod, "simulate_record", diverging)
    with pytest.raises(ConvergenceError, match="diverges"):
        refine_parameters(rec, TRUTH, free=["F_haft"], max_nfev=5)


def test_divergent_trial_points_are_rejected(clean_records, monkeypatch):
    import servoid.plants.pneumatic._refine as refine_mod

    rec = clean_records["thermo"].slice(0, 3000)
    real = refine_mod.simulate_record

    def fragile(params, record, controller=None):
        if params.d_k < 50.0:  # a region where the "simulation" diverges
            raise ModelError("a chamber pressure left (0, ∞)")
        return real(params, record, controller)

    monkeypatch.setattr(refine_mod, "simulate_record", fragile)
    out = refine_parameters(rec, TRUTH.with_(d_k=56.0), free=["d_k"],
                            bounds={"d_k": (10.0, 100.0)})
    assert abs(out.parameters.d_k - 55.0) < 0.05  # penalised trials rejected, optimum found


def test_options_and_records_are_checked(clean_records, known):
    with pytest.raises(OptionError, match="derivatives"):
        identify_multistep(clean_records, known, derivatives="finite-difference")
    with pytest.raises(DataError, match="missing: valve"):
        identify_multistep({k: v for k, v in clean_records.items() if k != "valve"}, known)
    with pytest.raises(ChannelError, match="S1 .* needs the channel 'x_v'"):
        identify_valve(clean_records["valve"].drop("x_v"))
    with pytest.raises(OptionError, match="free must name"):
        refine_parameters(clean_records["thermo"], TRUTH, free=["bore"])
    with pytest.raises(TypeError, match="known must be KnownConstants"):
        identify_thermodynamics(clean_records["thermo"], {"A_I": 1.0})


def test_known_constants_validation():
    with pytest.raises(DataError, match="lack A_II"):
        KnownConstants.from_mapping({"A_I": 1e-3})
    with pytest.raises(DataError, match="p_R must be < p_S"):
        KnownConstants.from_parameters(TRUTH).__class__(
            **{**KnownConstants.from_parameters(TRUTH).to_dict(), "p_R": 7e5})
    tight = KnownConstants(**{**KnownConstants.from_parameters(TRUTH).to_dict(), "V_0I": 1e-4})
    with pytest.raises(ModelError, match="V_0I leaves a dead volume"):
        tight.to_parameters()
