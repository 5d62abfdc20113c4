"""A real record through the experiment file: the DaISy flexible robot arm.

Writes the shipped record as a CSV with an experiment TOML, then lets
``servoid identify`` fit ARX, OE and a subspace model of the same order and
compares them on the held-back half — the comparison a test engineer makes
before choosing a model structure.

Run: python examples/flexible_arm.py [FOLDER]   (writes the CSV, the TOML and the four
reports into FOLDER; without FOLDER, into a new temporary folder)
"""

import sys
import tempfile
import warnings
from pathlib import Path

from servoid import ServoidWarning
from servoid.data import write_csv, write_experiment_spec
from servoid.datasets import load_daisy
from servoid.workflows import identify

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="servoid-arm-"))
out.mkdir(parents=True, exist_ok=True)
exp = load_daisy("robot_arm")  # torque → arm acceleration, 1024 samples, dt not given (1)
write_csv(exp, out / "robot_arm.csv", overwrite=True)

rows = []
for method, orders in [("arx", {"na": 4, "nb": 4}), ("oe", {"nb": 4, "nf": 4}),
                       ("n4sid", {"order": 4}),
                       ("oe", {"nb": [2, 4, 6], "nf": [2, 4, 6], "criterion": "bic"})]:
    table = {
        "data": {"file": "robot_arm.csv"},
        "channels": {"torque": {"role": "u"}, "acceleration": {"role": "y"}},
        "preprocess": {"detrend": "mean"},
        "identify": {"method": method, **orders},
        "report": {"folder": f"arm-{method}-results"},
    }
    path = write_experiment_spec(table, out / "arm.toml", overwrite=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)  # each verdict is in the report's notes
        result = identify(path, overwrite=True)
    rows.append((result.title, result.validation.fit_percent, len(result.notes)))

print(f"{'model':<48} {'validation fit':>15} {'notes':>6}")
for title, fit, notes in rows:
    print(f"{title:<48} {fit:>13.1f} % {notes:>6}")
print(f"reports: {out / 'arm-*-results' / 'report.html'}")
