"""The closed-loop workflow explains a two-step/one-step disagreement in words."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from servoid.plants.ehsa._workflow import _disagreement


def _result(values, stds):
    est = SimpleNamespace(names=["K", "omega_hp", "delta_hp"], parameters=np.array(values),
                          std=np.array(stds))
    return SimpleNamespace(estimate=est)


def test_explained_only_when_the_approaches_disagree():
    one = _result([3450.0, 163.3, 0.249], [2.0, 0.02, 2e-4])
    close = _result([3452.0, 163.31, 0.2491], [5.0, 0.05, 5e-4])  # within 4 combined σ
    assert _disagreement({"indirect": close, "one-step": one}) == []
    far = _result([4565.0, 163.31, 5.8], [230.0, 0.05, 0.15])  # K, delta_hp far apart
    (note,) = _disagreement({"indirect": far, "one-step": one})
    assert note.startswith("why two-step and one-step disagree on K, delta_hp ")
    assert _disagreement({"one-step": one}) == []
