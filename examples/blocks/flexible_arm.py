"""Block-oriented models against linear ones on a real record: the DaISy flexible arm.

Fits on the first half of the record (mean removed) and scores the free run on
the held-back second half: OE from ``fit_oe`` over a grid of orders, Hammerstein
and Wiener models, and the linear block alone fitted by the block models' own
search (a degree-1 polynomial Hammerstein model is exactly an OE model with unit
static gain times a slope). Prints one line per model, and the best OE orders
fitted from zero initial conditions (the arm's modes ring for longer than the
record half); writes nothing.
"""

import warnings

from servoid import ServoidError, ServoidWarning
from servoid.datasets import load_daisy
from servoid.estimate import fit_oe
from servoid.nonlinear import fit_block
from servoid.validate import validate

warnings.simplefilter("ignore", ServoidWarning)  # verdicts are not the point here
exp = load_daisy("robot_arm").detrend("mean")
half = exp.n_samples // 2
fit_part, held_back = exp.slice(0, half), exp.slice(half, exp.n_samples)

rows = []
scores = {}
for nb in range(2, 7):
    for nf in range(2, 7):
        try:
            scores[nb, nf] = validate(fit_oe(fit_part, nb, nf, 1), held_back).fit_percent
        except ServoidError:
            continue
best = max(scores, key=scores.__getitem__)
rows.append(("fit_oe, nb = nf = 4", scores[4, 4]))
rows.append((f"best fit_oe over nb, nf in 2..6: {best}", scores[best]))
from_rest = fit_oe(fit_part, *best, 1, initial="zero")
rows.append((f"fit_oe {best}, zero initial conditions", validate(from_rest, held_back).fit_percent))
for label, kwargs in (
        ("Hammerstein, cubic", {"structure": "hammerstein", "input_nonlinearity": "polynomial"}),
        ("Wiener, signed power", {"structure": "wiener", "output_nonlinearity": "power"}),
        ("linear block alone (degree 1)", {"structure": "hammerstein",
                                           "input_nonlinearity": "polynomial", "degree": 1})):
    est = fit_block(fit_part, nb=6, nf=6, nk=1, **kwargs)
    rows.append((f"{label}, nb = nf = 6", validate(est, held_back).fit_percent))
    if "power.exponent" in est.names:
        exponent = (est["power.exponent"], est.std[est.names.index("power.exponent")])

for label, score in rows:
    print(f"{label:<48} {score:6.1f} %")
print(f"Wiener exponent {exponent[0]:.3f} ± {exponent[1]:.3f} "
      f"({abs(exponent[0] - 1) / exponent[1]:.1f} σ from 1)")
