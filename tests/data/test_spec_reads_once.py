"""An experiment spec parses an unchanged rig file once.

A workflow needs the record for the split and again, whole, for the
feedback test; at 1e6 rows the second CSV parse cost as long as the fit.
The spec keeps its last record, read, calibrated and preprocessed (not
detrended), and reuses it while the file's size and modification time are
unchanged.
"""

import os

import numpy as np

from servoid.data import Experiment, _prepare, load_experiment_spec, write_csv


def _setup(tmp_path, n=400):
    rng = np.random.default_rng(0)
    exp = Experiment.from_arrays(0.01, u=rng.standard_normal(n), y=rng.standard_normal(n))
    write_csv(exp, tmp_path / "rec.csv")
    (tmp_path / "e.toml").write_text(
        '[data]\nfile = "rec.csv"\n[channels.u]\nsource = "u"\nrole = "u"\n'
        '[channels.y]\nsource = "y"\nrole = "y"\n[identify]\nmethod = "arx"\n')
    return load_experiment_spec(tmp_path / "e.toml")


def _count_reads(monkeypatch):
    calls = []
    real = _prepare.read_experiment

    def spy(*args, **kw):
        calls.append(args[0])
        return real(*args, **kw)

    monkeypatch.setattr(_prepare, "read_experiment", spy)
    return calls


def test_split_and_whole_record_read_the_file_once(tmp_path, monkeypatch):
    spec = _setup(tmp_path)
    calls = _count_reads(monkeypatch)
    estimation, _ = spec.records()
    whole = spec.load()
    assert len(calls) == 1
    assert whole.n_samples == 400 and estimation.n_samples == 200


def test_a_changed_file_is_read_again(tmp_path, monkeypatch):
    spec = _setup(tmp_path)
    calls = _count_reads(monkeypatch)
    first = spec.load()
    rng = np.random.default_rng(1)
    write_csv(Experiment.from_arrays(0.01, u=rng.standard_normal(300),
                                     y=rng.standard_normal(300)),
              tmp_path / "rec.csv", overwrite=True)
    st = os.stat(tmp_path / "rec.csv")
    os.utime(tmp_path / "rec.csv", ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    second = spec.load()
    assert len(calls) == 2
    assert (first.n_samples, second.n_samples) == (400, 300)
