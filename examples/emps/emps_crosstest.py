"""EMPS cross-test: which IDIM-LS pipeline predicts the other record better.

Fits the axis on one EMPS record with each pipeline ("published": the
reference's MATLAB script exactly; "servoid": servoid's filters) and
scores the parameters on the other record: the inverse model's relative
error (the other record processed by either pipeline, so both parameter
sets meet the same yardstick) and the closed-loop simulation of position
and force, with the force pulses of DATA_EMPS_PULSES as a disturbance.
Both directions. docs/emps.md quotes the output.
Data and reference: Janot, Gautier, Brunot, *Data Set and Reference Models
of EMPS*, 2019.
"""

import numpy as np

from servoid.datasets import load_emps
from servoid.plants.rigid import (
    CascadeController,
    fit_inverse_dynamics,
    inverse_dynamics_regression,
    simulate_rigid_loop,
)
from servoid.validate import relative_error

RECORDS = {"DATA_EMPS": load_emps(), "DATA_EMPS_PULSES": load_emps("validation")}
PIPELINES = ("published", "servoid")
notes = RECORDS["DATA_EMPS"].notes
controller = CascadeController(notes["kp"], notes["kv"], notes["gtau"], notes["saturation"])


def scores(axis_estimate, record, model):
    """Inverse-model errors (both yardsticks) and closed-loop errors on a record [%]."""
    out = {}
    for yardstick in PIPELINES:
        reg = inverse_dynamics_regression(record, model=model, pipeline=yardstick)
        out[f"inverse ({yardstick} proc.)"] = relative_error(
            reg.force, reg.regressors @ axis_estimate.parameters)
    pulses = record["pulse_force"] if "pulse_force" in record.names else None
    q = record["qm"]
    for start, q0, v0 in (("rest", None, 0.0), ("measured", q[0], (q[1] - q[0]) / record.dt)):
        sim = simulate_rigid_loop(axis_estimate.model, controller, record["qg"], record.dt,
                                  q0=q0, v0=v0, disturbance=pulses)
        out[f"loop position ({start})"] = relative_error(q, sim.position)
        out[f"loop force ({start})"] = relative_error(record["force"], sim.force)
    return out


for model in ("symmetric", "asymmetric"):
    table = {p: [] for p in PIPELINES}
    for fit_on, score_on in (("DATA_EMPS", "DATA_EMPS_PULSES"), ("DATA_EMPS_PULSES", "DATA_EMPS")):
        print(f"\n{model}: fitted on {fit_on}, scored on {score_on} [%]")
        for pipeline in PIPELINES:
            est = fit_inverse_dynamics(RECORDS[fit_on], model=model, pipeline=pipeline)
            s = scores(est, RECORDS[score_on], model)
            table[pipeline].append(s)
            print(f"  {pipeline:<9} fit {est.options['relative_error']:.4f} | "
                  + " | ".join(f"{k} {v:.{6 if 'position' in k else 4}f}"
                               for k, v in s.items()))
    print("  mean over both directions, published − servoid (negative: published better):")
    keys = table["published"][0].keys()
    print("   " + " | ".join(
        f"{k} {np.mean([a[k] - b[k] for a, b in zip(*table.values(), strict=True)]):+.2g}"
        for k in keys))

pulses = RECORDS["DATA_EMPS_PULSES"]
est = fit_inverse_dynamics(RECORDS["DATA_EMPS"], model="symmetric", pipeline="published")
print("\npublished symmetric estimate on DATA_EMPS_PULSES, simulated from rest [%]:")
for label, disturbance in (("with the pulses as disturbance", pulses["pulse_force"]),
                           ("without them", None)):
    sim = simulate_rigid_loop(est.model, controller, pulses["qg"], pulses.dt,
                              disturbance=disturbance)
    print(f"  {label:<31} position {relative_error(pulses['qm'], sim.position):.4f}, "
          f"force {relative_error(pulses['force'], sim.force):.2f}")
