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
