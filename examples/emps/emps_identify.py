"""EMPS servo axis: mass and friction from closed-loop data, through the API.

The same steps as ``servoid identify examples/emps/emps.toml`` (which also
writes the HTML report): inverse-model least squares, the identified axis
simulated in its known loop, a closed-loop output-error refinement; and the
two pipelines (``"published"``, the reference's script; ``"servoid"``, its own
filters) side by side with the published values (``published.json``).
Data and reference: Janot, Gautier, Brunot, *Data Set and Reference Models
of EMPS*, 2019.

Run: python examples/emps/emps_identify.py [FOLDER]   (writes a figure and results.json
into FOLDER; without FOLDER, into a new temporary folder)
"""

import json
import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from servoid.datasets import load_emps
from servoid.plants.rigid import (
    CascadeController,
    fit_closed_loop_oe,
    fit_inverse_dynamics,
    simulate_rigid_loop,
)
from servoid.report import write_json
from servoid.validate import relative_error

PUBLISHED = json.loads((Path(__file__).parent / "published.json").read_text(encoding="utf-8"))

exp = load_emps()
controller = CascadeController(exp.notes["kp"], exp.notes["kv"], exp.notes["gtau"], 10.0)

ls = fit_inverse_dynamics(exp, model="symmetric", cutoff=100.0, decimation=10)
print(ls)

print("\nIDIM-LS on DATA_EMPS, value ± std; relative error of τ [%]; condition number of Φ")
for model in ("symmetric", "asymmetric"):
    published = PUBLISHED[model]
    for pipeline in ("published", "servoid"):
        est = fit_inverse_dynamics(exp, model=model, pipeline=pipeline)
        print(f"  {model:<10} {pipeline:<10} " + ", ".join(
            f"{n} {v:.4f} ± {s:.4f}" for n, v, s in zip(est.names, est.parameters, est.std,
                                                          strict=True))
              + f"; {est.options['relative_error']:.4f} %; {est.options['condition_unscaled']:.2f}")
    print(f"  {model:<10} {'Janot 2019':<10} " + ", ".join(
        f"{n} {p['value']:.4f}" + (f" ± {p['std']:.4f}" if p["std"] is not None else "")
        for n, p in published["parameters"].items())
          + f"; {published['relative_error']:.4f} %"
          + (f"; {published['condition']:.2f}" if "condition" in published else ""))
no_trim = {f: fit_inverse_dynamics(exp, pipeline="servoid", trim=0, decimation_filter=f)
           for f in ("fir", "iir")}
print("  servoid pipeline without the trim: relative error "
      + ", ".join(f"{e.options['relative_error']:.4f} % ({f.upper()})" for f, e in no_trim.items()))

sim = simulate_rigid_loop(ls.model, controller, exp["qg"], exp.dt)
print(f"\nclosed loop from rest: position {relative_error(exp['qm'], sim.position):.4f} % "
      f"(published {PUBLISHED['closed_loop']['position']} %), force "
      f"{relative_error(exp['force'], sim.force):.2f} % "
      f"(published {PUBLISHED['closed_loop']['force']} %)")

oe = fit_closed_loop_oe(exp, controller, ls, output="both")
print(oe)
errors = oe.options["relative_error"]
print(f"closed-loop OE: position {errors['position']:.4f} %, force {errors['force']:.2f} %; "
      f"Fv {100 * (oe['Fv'] / ls['Fv'] - 1):+.1f} %, Fc {100 * (oe['Fc'] / ls['Fc'] - 1):+.1f} % "
      "from IDIM-LS")

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="servoid-emps-"))
out.mkdir(parents=True, exist_ok=True)
fig, ax = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
ax[0].plot(exp.time, exp["force"], color="0.2", lw=0.8, label="measured")
ax[0].plot(exp.time, sim.force, color="C1", lw=0.6, label="IDIM-LS axis in its loop")
ax[0].set_ylabel("force [N]")
ax[0].legend(fontsize=8)
ax[1].plot(exp.time, 1e6 * (exp["qm"] - sim.position), color="C1", lw=0.6)
ax[1].set_ylabel("position error [µm]")
ax[1].set_xlabel("time [s]")
fig.tight_layout()
fig.savefig(out / "closed_loop.png", dpi=100)
write_json({"idim_ls": ls.to_dict(), "closed_loop_oe": oe.to_dict()}, out / "results.json",
           overwrite=True)
print(f"wrote {out / 'closed_loop.png'} and {out / 'results.json'}")
