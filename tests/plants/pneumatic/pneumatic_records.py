"""Records of the multi-step tests (helpers), from the servopneumatic simulator.

Channel names are the bench's (SI after calibration): u, x_ref, x_k, x_v,
p_I, p_II, T_I, T_II, mdot_I, mdot_II, v_k, a_k, f_ext.  The mass flows are
clipped at the 4 g/s sensor range, as the hot-wire sensor of [S2] reads.
"""

from __future__ import annotations

import numpy as np

from servoid.data import Experiment
from servoid.plants.pneumatic import PNEUMATIC_NOMINAL, PositionController, simulate_pneumatic

TRUTH = PNEUMATIC_NOMINAL
DT = 1e-4  # 10 kHz (P4)
DT_VALVE = 5e-5  # 20 kHz (P2)
MDOT_RANGE = 4e-3
#: Sensor noise of P4(b) (std): 2 µm position, 0.5 µm spool, 200 Pa, 1e-5 kg/s (0.25 % of
#: range), 1 mm/s, 0.05 m/s², 0.1 K, 0.5 N.
NOISE = {"x_k": 2e-6, "x_v": 5e-7, "p_I": 200.0, "p_II": 200.0, "mdot_I": 1e-5,
         "mdot_II": 1e-5, "v_k": 1e-3, "a_k": 0.05, "T_I": 0.1, "T_II": 0.1, "f_ext": 0.5}


def to_record(res, name, noise=None, rng=None, mdot_range=MDOT_RANGE):
    """An Experiment with the bench's channel names from a simulator response."""
    side = {"x_v": res.x_v, "p_I": res.p_I, "p_II": res.p_II, "T_I": res.T_I,
            "T_II": res.T_II, "mdot_I": res.m_dot_I, "mdot_II": res.m_dot_II,
            "v_k": res.x_k_dot, "a_k": res.x_k_ddot, "f_ext": res.f_ext}
    y = np.asarray(res.x_k)
    if noise:
        side = {k: v + noise.get(k, 0.0) * rng.standard_normal(v.size) for k, v in side.items()}
        y = y + noise["x_k"] * rng.standard_normal(y.size)
    side["mdot_I"] = np.clip(side["mdot_I"], -mdot_range, mdot_range)
    side["mdot_II"] = np.clip(side["mdot_II"], -mdot_range, mdot_range)
    units = {"u": "V", "x_ref": "m", "x_k": "m", "x_v": "m", "p_I": "Pa", "p_II": "Pa",
             "T_I": "K", "T_II": "K", "mdot_I": "kg/s", "mdot_II": "kg/s", "v_k": "m/s",
             "a_k": "m/s²", "f_ext": "N"}
    kw = {"u": res.u, "y": y, "side": side, "units": units,
          "names": {"u": "u", "y": "x_k", "r": "x_ref"}}
    if res.r is not None:
        kw["r"] = res.r
    return Experiment.from_arrays(res.dt, name=name, **kw)


def valve_response(duration=0.4, params=TRUTH):
    """±5 V rectangle at 25 Hz, open loop, 20 kHz (P2)."""
    t = np.arange(round(duration / DT_VALVE)) * DT_VALVE
    u = np.where(np.sin(2 * np.pi * 25 * t + 1e-9) >= 0, 5.0, -5.0)
    return simulate_pneumatic(params, u, DT_VALVE)


def sine_response(duration=2.0, amplitude=0.02, freq=1.0, force=0.0, params=TRUTH):
    """Closed-loop sine of the reference (spec §2 'Checked' run), optional force square."""
    t = np.arange(round(duration / DT)) * DT
    f_ext = None if force == 0.0 else np.where(np.sin(2 * np.pi * 0.75 * t) >= 0, force, -force)
    return simulate_pneumatic(params, None, DT, r=amplitude * np.sin(2 * np.pi * freq * t),
                              controller=PositionController(), f_ext=f_ext)
