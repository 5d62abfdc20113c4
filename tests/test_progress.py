"""Progress on stderr: a batch counter, stage lines and notices, silent unless switched on.

The stage tests drive the drawing with a fake clock (``_progress._now``) and
call ``_tick`` themselves, as the background thread would every 0.1 s: no
test waits on a timer.
"""

from __future__ import annotations

import io

import pytest

import servoid._progress as progress
from servoid._progress import Progress, configure, notice, stage, take_notices


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


class _Clock:
    """A fake monotonic clock; ``run_to`` ticks every 0.1 s as the thread does.

    Times are 1000 + n/10 s: differences of whole and half seconds are exact.
    """

    def __init__(self) -> None:
        self.n = 0
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t

    def run_to(self, t: float) -> None:
        while self.n < round(10 * t):
            self.n += 1
            self.t = 1000.0 + self.n / 10
            progress._tick(self.t)


class _Timed(io.StringIO):
    """A stream that remembers when (on the fake clock) each write came."""

    def __init__(self, clock: _Clock, tty: bool = False) -> None:
        super().__init__()
        self.clock, self.tty, self.times = clock, tty, []

    def isatty(self) -> bool:
        return self.tty

    def write(self, text: str) -> int:
        self.times.append(self.clock.t - 1000.0)
        return super().write(text)


@pytest.fixture
def clock(monkeypatch):
    fake = _Clock()
    monkeypatch.setattr(progress, "_now", fake)
    monkeypatch.setattr(progress, "_start_ticker", lambda: None)  # the test ticks
    yield fake
    configure(False)


def test_batch_counter_on_a_terminal_and_in_a_log():
    tty = _Tty()
    bar = Progress(4, "identifying", stream=tty, enabled=True)
    for ok in (True, False, True, True):
        bar.update(ok=ok)
    text = tty.getvalue()
    assert "\r[" in text and text.endswith("\n")
    assert "identifying 4/4, 1 failed, 0 remaining" in text
    log = io.StringIO()
    bar = Progress(3, "identifying", stream=log, enabled=True)
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


def test_a_batch_follows_the_command_line_switch_by_default(clock):
    out = io.StringIO()
    Progress(1, "simulating units", stream=out).update()  # the API: silent
    assert out.getvalue() == ""
    configure(True, out)
    Progress(1, "simulating units").update()  # the command line: on, to its stream
    assert out.getvalue().startswith("simulating units 1/1")


def test_the_api_is_silent(clock):
    out = io.StringIO()
    configure(False, out)
    with stage("fitting"):
        clock.run_to(5.0)
    notice("a warning")
    clock.run_to(10.0)
    assert out.getvalue() == "" and take_notices() == []


def test_a_quick_stage_says_nothing_and_a_long_one_plain_lines_on_a_pipe(clock):
    out = io.StringIO()
    configure(True, out)
    with stage("quick"):
        clock.run_to(1.0)
    assert out.getvalue() == ""
    with stage("fitting the one-step model"):
        clock.run_to(3.5)
    lines = out.getvalue().splitlines()
    assert lines[0] == "servoid: fitting the one-step model … 0:01"  # 2 s quiet since 0 s
    assert lines[-1] == "servoid: fitting the one-step model done in 0:02"  # ran 2.5 s
    assert "\r" not in out.getvalue() and "\x1b" not in out.getvalue()


def test_short_steps_one_after_another_leave_no_long_silence(clock):
    """Steps of 1.9 s each: none is long, yet the output never stops for more than 2 s."""
    out = _Timed(clock)
    configure(True, out)
    with stage("identify"):
        at = 0.0
        for k in range(6):
            with stage(f"step {k}"):
                at += 1.9
                clock.run_to(at)
    gaps = [b - a for a, b in zip([0.0, *out.times], [*out.times, at], strict=True)]
    assert max(gaps) <= progress._STAGE_DELAY + progress._TICK + 1e-9, (gaps, out.getvalue())
    assert "servoid: step 1 … 0:00" in out.getvalue()  # the step running when 2 s had passed


def test_a_long_stage_on_a_pipe_writes_a_line_every_two_seconds(clock):
    out = _Timed(clock)
    configure(True, out)
    with stage("simulating the bench"):
        clock.run_to(125.0)
    lines = out.getvalue().splitlines()
    assert lines[0] == "servoid: simulating the bench … 0:02"
    assert lines[1] == "servoid: simulating the bench … 0:04"
    assert lines[-1] == "servoid: simulating the bench done in 2:05"
    gaps = [b - a for a, b in zip([0.0, *out.times], [*out.times, 125.0], strict=True)]
    assert max(gaps) <= progress._STAGE_DELAY + progress._TICK + 1e-9, gaps  # never silent


def test_on_a_terminal_one_line_is_redrawn_and_an_inner_stage_takes_it_over(clock):
    out = _Timed(clock, tty=True)
    configure(True, out)
    with stage("simulating the bench"):
        clock.run_to(4.0)
        with stage("compiling"):
            mark = len(out.getvalue())
            clock.run_to(7.0)
            during = out.getvalue()[mark:]
        clock.run_to(8.0)
    text = out.getvalue()
    assert "\rservoid: simulating the bench … 0:02\x1b[K" in text
    assert "\rservoid: simulating the bench … 0:03\x1b[K" in text  # redrawn each second
    assert "\rservoid: compiling … 0:00\x1b[K" in during  # after half a second
    assert "simulating" not in during  # one writer at a time
    assert "\rservoid: compiling done in 0:03\x1b[K\n" in text
    assert text.endswith("\rservoid: simulating the bench done in 0:08\x1b[K\n")


def test_an_inner_stage_shown_briefly_gives_the_line_back(clock):
    out = io.StringIO()
    configure(True, _tty := _Tty())
    with stage("outer"):
        clock.run_to(3.0)
        with stage("inner"):
            clock.run_to(3.8)
        clock.run_to(4.0)
    text = _tty.getvalue()
    assert "\rservoid: inner … 0:00\x1b[K\r\x1b[K\rservoid: outer … 0:03" in text
    assert "inner done" not in text and out.getvalue() == ""


def test_a_stage_line_leaves_a_moving_batch_bar_alone(clock, monkeypatch):
    monkeypatch.setattr(progress, "_MIN_INTERVAL", 0.0)  # the bar redraws at every item
    out = _Tty()
    configure(True, out)
    with stage("bench fleet"):
        bar = Progress(8, "simulating units", failures=False)
        for k in range(1, 5):  # an item every 1.5 s: the bar keeps the line
            clock.run_to(1.5 * k)
            bar.update()
        assert "servoid: bench fleet" not in out.getvalue()
        clock.run_to(8.5)  # no item for 2.5 s: the stage speaks, on a line of its own
        bar.update()
    text = out.getvalue()
    assert "simulating units 4/8, 4 remaining" in text  # no "failed" for a batch that cannot
    last_bar = text.index("simulating units 4/8")
    stage_line = text.index("\rservoid: bench fleet … 0:08")
    assert text[last_bar:stage_line].endswith("\x1b[K\n")  # the bar's line was ended first


def test_on_a_pipe_a_slow_batch_is_never_silent_for_long(clock, monkeypatch):
    monkeypatch.setattr(progress, "_LINE_INTERVAL", 0.0)  # a bar line at every unit
    out = _Timed(clock)
    configure(True, out)
    with stage("bench fleet"):
        clock.run_to(2.5)  # start-up: the stage speaks
        bar = Progress(10, "simulating units", failures=False)
        for k in range(10):  # a unit every 6 s: the stage speaks between the bar's lines
            clock.run_to(2.5 + 6 * (k + 1))
            bar.update()
    lines = out.getvalue().splitlines()
    first = next(k for k, line in enumerate(lines) if line.startswith("simulating units 1/10"))
    assert lines[first - 1].startswith("servoid: bench fleet …")  # before the first unit
    gaps = [b - a for a, b in zip([0.0, *out.times], [*out.times, 62.5], strict=True)]
    assert max(gaps) <= progress._STAGE_DELAY + progress._TICK + 1e-9, gaps
    assert lines[-1] == "servoid: bench fleet done in 1:02"


def test_a_step_that_starts_after_the_batch_spoke_is_named(clock):
    """A batch bar holds the line against the stages around it, not against a new step."""
    out = io.StringIO()
    configure(True, out)
    with stage("fleet"):
        bar = Progress(25, "identifying")
        bar.update()  # the first record, run here; then the workers must start
        clock.run_to(1.0)
        with stage("starting the Dask workers"):
            clock.run_to(6.0)
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("identifying 1/25")
    assert lines[1] == "servoid: starting the Dask workers … 0:00"  # half a second in
    assert lines[-1] == "servoid: starting the Dask workers done in 0:05"


def test_notices_show_while_the_run_goes_on_and_the_rest_are_taken(clock):
    out = _Timed(clock)
    configure(True, out)
    with stage("identify"):
        notice("servoid: warning: the Python integrator runs (about 3 min)")
        clock.run_to(1.5)
        notice("servoid: warning: a late one")
        clock.run_to(1.6)
    assert out.getvalue() == "servoid: warning: the Python integrator runs (about 3 min)\n"
    assert out.times == [1.0]
    assert take_notices() == ["servoid: warning: a late one"]
    assert take_notices() == []


def test_a_terminal_notice_ends_the_stage_line_and_the_stage_comes_back(clock):
    out = _Tty()
    configure(True, out)
    with stage("fitting"):
        clock.run_to(2.5)
        notice("servoid: warning: slow")
        clock.run_to(3.6)
    text = out.getvalue()
    assert "\rservoid: warning: slow\x1b[K\n\rservoid: fitting … 0:03" in text


def test_a_stage_ended_by_an_error_says_it_stopped(clock):
    out = io.StringIO()
    configure(True, out)
    with pytest.raises(KeyboardInterrupt), stage("fitting"):
        clock.run_to(3.0)
        raise KeyboardInterrupt
    assert out.getvalue().splitlines()[-1] == "servoid: fitting stopped after 0:03"


def test_live_stream_tells_a_pipe_from_a_buffer(tmp_path):
    assert not progress.live_stream(io.StringIO())
    assert progress.live_stream(_Tty())
    with open(tmp_path / "log.txt", "w", encoding="utf-8") as log:
        assert progress.live_stream(log)


def test_a_real_compilation_is_named_and_a_cached_load_is_not(clock, monkeypatch):
    import numba

    monkeypatch.setattr(progress._S, "watching", False)
    out = io.StringIO()
    configure(True, out)
    # show a stage as soon as it opens, as if 10 s had passed
    monkeypatch.setattr(progress, "_start_ticker", lambda: progress._tick(clock.t + 10.0))
    progress.watch_compiles()

    @numba.njit(cache=False)
    def _square_plus_one(x):  # a new function: numba must compile it here
        return x * x + 1.0

    assert _square_plus_one(2.0) == 5.0
    first = out.getvalue()
    assert _square_plus_one(3.0) == 10.0  # compiled already: nothing more to say
    # cache=False: nothing is kept for later runs, and the line does not promise it
    assert "servoid: compiling test_progress._square_plus_one … 0:10\n" in first
    assert out.getvalue() == first
