"""Progress on stderr: a batch counter and stage lines, silent unless switched on."""

from __future__ import annotations

import io
import time

import servoid._progress as progress
from servoid._progress import Progress, configure, stage


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_batch_counter_on_a_terminal_and_in_a_log():
    tty = _Tty()
    bar = Progress(4, "identifying", stream=tty)
    for ok in (True, False, True, True):
        bar.update(ok=ok)
    text = tty.getvalue()
    assert "\r[" in text and text.endswith("\n")
    assert "identifying 4/4, 1 failed, 0 remaining" in text
    log = io.StringIO()
    bar = Progress(3, "identifying", stream=log)
    bar.update(skipped=True)
    bar.update()
    bar.update(ok=False)
    lines = log.getvalue().splitlines()
    assert lines[-1].startswith("identifying 3/3, 1 unchanged, 1 failed, 0 remaining")
    assert "\r" not in log.getvalue()
    quiet = io.StringIO()
    bar = Progress(2, "x", stream=quiet, enabled=False)
    bar.update()
    bar.update()
    assert quiet.getvalue() == ""


def test_stage_line_appears_only_for_long_steps_and_only_when_switched_on(monkeypatch):
    monkeypatch.setattr(progress, "_STAGE_DELAY", 0.05)
    out = io.StringIO()
    with stage("fitting"):  # off by default: the API is silent
        time.sleep(0.12)
    configure(True, out)
    try:
        with stage("quick"):
            pass
        assert out.getvalue() == ""
        with stage("fitting the one-step model"):
            time.sleep(0.12)
    finally:
        configure(False)
    assert "servoid: fitting the one-step model …" in out.getvalue()
    assert out.getvalue().endswith("done in 0:00\x1b[K\n")


def test_an_inner_stage_takes_the_line_over(monkeypatch):
    monkeypatch.setattr(progress, "_STAGE_DELAY", 0.05)
    out = io.StringIO()
    configure(True, out)
    try:
        with stage("simulating the bench"):
            time.sleep(0.12)
            with stage("compiling"):
                mark = len(out.getvalue())
                time.sleep(0.25)
                during = out.getvalue()[mark:]
    finally:
        configure(False)
    assert "compiling …" in during and "simulating" not in during  # one writer at a time
    assert "simulating the bench … done in" in out.getvalue()


def test_a_real_compilation_is_named_and_a_cached_load_is_not(monkeypatch):
    import numba

    monkeypatch.setattr(progress, "_STAGE_DELAY", 0.0)
    monkeypatch.setitem(progress._STAGES, "watching", False)
    out = io.StringIO()
    configure(True, out)
    try:
        progress.watch_compiles()

        @numba.njit(cache=False)
        def _square_plus_one(x):  # a new function: numba must compile it here
            return x * x + 1.0

        time.sleep(0.01)
        assert _square_plus_one(2.0) == 5.0
        first = out.getvalue()
        assert _square_plus_one(3.0) == 10.0  # compiled already: nothing more to say
    finally:
        configure(False)
    assert "compiling test_progress._square_plus_one (first use; cached for later runs)" \
        in first
    assert out.getvalue() == first
