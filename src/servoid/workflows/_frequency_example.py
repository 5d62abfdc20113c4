"""The example record of ``method = "frequency"``: a multisine test of an actuator on the rig.

The plant is the continuous ``ω_n²/(s² + 2ζω_n s + ω_n²)`` with ω_n = 2π·8 rad/s and
ζ = 0.4 (its resonance: 2.70 dB at 6.60 Hz), behind a mild cubic (``u + 0.05·u³``: a
little odd distortion), recorded by the virtual rig (20× oversampled, ZOH input, white
noise), driven by a random-odd multisine of 4 realisations × 2 periods (one transient
period each); the plan file lies beside the data file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["multisine_test"]

_DT = 0.01


def multisine_test(folder: Path, seed: int = 0) -> Path:
    """Write the record, its plan file and its experiment file; return the experiment file."""
    from ..bench import simulate_lti
    from ..data import Experiment, write_csv, write_experiment_spec
    from ..models import TransferFunction
    from ..signals import plan_multisine, random_multisine

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    wn = 2 * np.pi * 8.0
    plant = TransferFunction([wn**2], [1.0, 2 * 0.4 * wn, wn**2])
    plan = plan_multisine(_DT, 0.2, 25.0, period=256, lines="random-odd", rng=7,
                          realisations=4, periods=2, transient_periods=1)
    u = random_multisine(plan, rng=seed).values
    exp = simulate_lti(plant, u + 0.05 * u**3, _DT, noise_std=0.02, rng=1000 + seed)
    write_csv(Experiment.from_arrays(_DT, u=u, y=exp["y"]), folder / "record.csv",
              overwrite=True)
    plan.write(folder / "record.plan.json", overwrite=True)
    path = folder / "experiment.toml"
    write_experiment_spec({
        "data": {"file": "record.csv"},
        "channels": {"u": {"role": "u", "unit": "V"}, "y": {"role": "y", "unit": "mm"}},
        "acceptance": {"bandwidth_min": 5.0, "resonance_peak_max": 6.0},
        "identify": {"method": "frequency", "n_poles": 2, "n_zeros": 0,
                     "phase_frequency": 5.0},
    }, path, overwrite=True)
    return path
