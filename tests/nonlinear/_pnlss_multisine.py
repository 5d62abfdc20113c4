"""The frequency method's example multisine test, as a PNLSS experiment file."""

from __future__ import annotations

from servoid.data import write_experiment_spec
from servoid.workflows._frequency_example import multisine_test


def multisine_pnlss(folder, **identify):
    """Write the multisine test (4 realisations × 2 periods, its plan beside the data file)
    and an experiment file fitting it by PNLSS with `identify`'s keys; the file's path."""
    multisine_test(folder)
    path = folder / "pnlss.toml"
    write_experiment_spec({"data": {"file": "record.csv"},
                           "channels": {"u": {"role": "u", "unit": "V"},
                                        "y": {"role": "y", "unit": "mm"}},
                           "identify": {"method": "pnlss", "n_states": 2, **identify}}, path)
    return path
