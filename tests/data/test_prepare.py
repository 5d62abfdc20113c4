"""prepare(spec): the records of an experiment file and what was read, each file hashed once."""

from __future__ import annotations

import hashlib
import os
import time
import warnings

import numpy as np
import pytest

from servoid import DataError, OptionError, ServoidWarning
from servoid.data import (
    Experiment,
    ExperimentSet,
    ExperimentSpec,
    InputFile,
    PreparedData,
    _digest,
    _prepare,
    file_sha256,
    load_experiment_spec,
    prepare,
    write_csv,
)

_CHANNELS = '[channels.u]\nsource = "u"\nrole = "u"\n[channels.y]\nsource = "y"\nrole = "y"\n'


def _record(n: int, seed: int) -> Experiment:
    rng = np.random.default_rng(seed)
    return Experiment.from_arrays(0.01, u=rng.standard_normal(n), y=rng.standard_normal(n))


def _aged(path):
    """Date a file an hour back, as a rig file recorded before the run is."""
    hour_ago = time.time_ns() - 3600 * 10**9
    os.utime(path, ns=(hour_ago, hour_ago))


def _split_spec(tmp_path, n=400, extra=""):
    write_csv(_record(n, 0), tmp_path / "rec.csv")
    (tmp_path / "e.toml").write_text(f'[data]\nfile = "rec.csv"\n{_CHANNELS}{extra}')
    return load_experiment_spec(tmp_path / "e.toml")


def test_a_split_record_gives_two_halves_and_the_file_with_its_digest(tmp_path):
    spec = _split_spec(tmp_path, extra='[preprocess]\ndetrend = "mean"\n')
    prepared = prepare(spec)
    assert prepared.estimation.n_samples == 200 and len(prepared.validations) == 1
    assert prepared.validations[0].n_samples == 200
    (read,) = prepared.inputs
    raw = (tmp_path / "rec.csv").read_bytes()
    assert read == InputFile(tmp_path / "rec.csv", "estimation", "csv", len(raw),
                             hashlib.sha256(raw).hexdigest())
    assert prepared.digest(tmp_path / "rec.csv") == hashlib.sha256(raw).hexdigest()
    # the validation half loses the estimation half's mean, not its own (exact: one sum)
    mean = float(np.mean(spec.load(detrend=False)["y"][:200]))
    np.testing.assert_allclose(prepared.validations[0]["y"],
                               spec.load(detrend=False)["y"][200:] - mean, rtol=0, atol=1e-15)


def test_the_spec_records_are_prepares(tmp_path):
    spec = _split_spec(tmp_path)
    est, (val,) = spec.records()
    prepared = prepare(tmp_path / "e.toml")  # a path is read as an experiment file
    np.testing.assert_array_equal(est["u"], prepared.estimation["u"])
    np.testing.assert_array_equal(val["y"], prepared.validations[0]["y"])
    assert prepared.spec == spec


def test_separate_validation_records_are_listed_after_the_estimation_set(tmp_path):
    for k, name in enumerate(("a.csv", "b.csv", "v.csv")):
        write_csv(_record(300, k), tmp_path / name)
    (tmp_path / "e.toml").write_text(
        f'[data]\nfile = ["a.csv", "b.csv"]\n{_CHANNELS}[validation]\nfile = "v.csv"\n')
    prepared = prepare(tmp_path / "e.toml")
    assert isinstance(prepared.estimation, ExperimentSet)
    assert [(f.path.name, f.role) for f in prepared.inputs] == [
        ("a.csv", "estimation"), ("b.csv", "estimation"), ("v.csv", "validation")]
    assert [f.size for f in prepared.inputs] == [
        (tmp_path / n).stat().st_size for n in ("a.csv", "b.csv", "v.csv")]


def test_a_path_that_was_not_read_has_no_digest(tmp_path):
    prepared = prepare(_split_spec(tmp_path))
    with pytest.raises(OptionError, match=r"other\.csv is not an input of this experiment"):
        prepared.digest(tmp_path / "other.csv")


def test_prepared_data_checks_what_it_holds(tmp_path):
    prepared = prepare(_split_spec(tmp_path))
    with pytest.raises(TypeError, match="validations must be a non-empty tuple of Experiment"):
        PreparedData(prepared.spec, prepared.estimation, (), prepared.inputs)


def test_a_file_that_changes_while_it_is_read_is_refused(tmp_path, monkeypatch):
    spec = _split_spec(tmp_path)
    real = _prepare.read_experiment

    def logger_still_writing(path, *args, **kw):
        exp = real(path, *args, **kw)
        with open(path, "a", encoding="utf-8") as f:
            f.write("4.0,1.0,1.0\n")
        return exp

    monkeypatch.setattr(_prepare, "read_experiment", logger_still_writing)
    with pytest.raises(DataError, match=r"rec\.csv changed while servoid read it"):
        prepare(spec)


def test_a_run_hashes_its_rig_file_once(tmp_path, monkeypatch):
    # results.json, the report's page and provenance and manifest.json each name the record by
    # its SHA-256; before prepare's digests a run of method arx hashed the CSV 6 times for them
    from servoid.workflows import identify

    spec = _split_spec(tmp_path, n=600)
    raw = (tmp_path / "rec.csv").read_bytes()  # < 1 MiB: one update() per hash of it
    # the file is as old as a rig file recorded before its run; its change time cannot be
    # set back, so the margin that keeps a file changed seconds ago from being remembered
    # is waived here
    monkeypatch.setattr(_digest, "_RACY", 0.0)
    _digest._forget()
    hashed = []
    real = hashlib.sha256

    class Counting:
        def __init__(self, data=b""):
            self._h = real(data)

        def update(self, data):
            hashed.append(bytes(data) == raw)
            self._h.update(data)

        def hexdigest(self):
            return self._h.hexdigest()

        def digest(self):
            return self._h.digest()

    monkeypatch.setattr(hashlib, "sha256", Counting)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)  # noise in, noise out: not the point
        identify(spec, tmp_path / "out")
    assert sum(hashed) == 1


def test_a_digest_is_never_stale(tmp_path):
    # same size, same modification time, other bytes: the change time tells (and a file
    # changed within the last seconds is not remembered at all)
    path = tmp_path / "rec.csv"
    path.write_bytes(b"time,u\n0,1\n")
    _aged(path)
    first = file_sha256(path)
    st = path.stat()
    path.write_bytes(b"time,u\n0,2\n")
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert file_sha256(path) == hashlib.sha256(b"time,u\n0,2\n").hexdigest() != first
    path.write_bytes(b"time,u\n0,3\n")
    assert file_sha256(path) == hashlib.sha256(b"time,u\n0,3\n").hexdigest()


def test_a_spec_built_in_python_is_checked_like_the_file(tmp_path):
    from servoid.data import ChannelSpec

    spec = ExperimentSpec("rec.csv", "csv", [ChannelSpec("y", "y", "y", gain=2)],
                          csv={"delimiter": ";"}, base_dir=tmp_path)
    assert spec.channels[0].gain == 2.0 and isinstance(spec.channels, tuple)
    assert ExperimentSpec.from_dict(spec.to_dict(), base_dir=tmp_path) == spec
    with pytest.raises(OptionError, match=r"csv holds unknown option\(s\) sep"):
        ExperimentSpec("rec.csv", "csv", (ChannelSpec("y", "y"),), csv={"sep": ";"})
    with pytest.raises(DataError, match=r"skip_rows apply to CSV files only, this is tdms"):
        ExperimentSpec("rec.tdms", "tdms", (ChannelSpec("y", "y"),), csv={"skip_rows": 2})
    with pytest.raises(DataError, match=r"ExperimentSpec dt must be a finite number > 0"):
        ExperimentSpec("rec.csv", "csv", (ChannelSpec("y", "y"),), dt=-1.0)
