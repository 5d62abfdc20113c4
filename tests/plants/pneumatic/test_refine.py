"""Grey-box refinement of the assembled set with the compiled simulator."""

from __future__ import annotations

import numpy as np
from pneumatic_records import TRUTH

from servoid.plants.pneumatic import (
    PositionController,
    compare_record,
    estimate_controller,
    refine_parameters,
)


def test_refinement_recovers_a_perturbed_subset(clean_records):
    rec = clean_records["thermo"].slice(0, 5000)  # 0.5 s: stick–slip and the force steps
    start = TRUTH.with_(c_k=126.0, kappa=1.39)
    out = refine_parameters(rec, start, free=["c_k", "kappa"],
                            controller=PositionController())
    # noise-free data from the model: back to the truth within the solver tolerance
    assert abs(out.parameters.c_k / 120.0 - 1) < 1e-4
    assert abs(out.parameters.kappa / 1.4 - 1) < 1e-5
    ci = out.estimate.confidence_intervals()
    assert np.all(ci[:, 0] <= out.estimate.parameters) and np.all(
        out.estimate.parameters <= ci[:, 1])
    assert out.free == ("c_k", "kappa") and out.start is start
    assert set(out.noise_std) == {"p_I", "p_II", "x_k"}
    assert out.to_dict()["free"] == ["c_k", "kappa"]


def test_controller_reconstruction_and_comparison(clean_records):
    rec = clean_records["validation"]
    ctrl = estimate_controller(rec)
    assert abs(ctrl.K_p - 300.0) < 1e-6 and abs(ctrl.K_d - 5.0) < 1e-8  # exact law, no noise
    comp = compare_record(TRUTH, rec)
    assert comp.closed_loop and comp.notes  # reconstructed, and said so
    assert min(comp.fit.values()) > 99.9
    assert comp.to_dict()["controller"]["K_p"] == ctrl.K_p
