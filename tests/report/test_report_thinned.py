"""Long signals are thinned to what a figure can show (M4: first, last, min, max per bucket)."""

import numpy as np

from servoid._drawing import thinned


def test_short_signals_are_drawn_whole():
    t = np.arange(8000.0)
    y = np.sin(t)
    tt, yy = thinned(t, y, buckets=2000)
    assert tt is t and yy is y


def test_every_bucket_keeps_its_extremes_and_ends_in_time_order():
    rng = np.random.default_rng(0)
    n, buckets = 100_003, 100
    t = np.arange(n) * 1e-3
    y = np.cumsum(rng.standard_normal(n))
    y[54_321] = 1e3  # a spike the picture must show
    tt, yy = thinned(t, y, buckets=buckets)
    assert np.all(np.diff(tt) > 0)  # strictly increasing: time order, no repeats
    assert tt.size <= 4 * buckets + n % buckets
    assert yy.max() == y.max() == 1e3 and yy.min() == y.min()
    size = n // buckets
    for b in range(buckets):  # each bucket's min, max, first and last sample are kept
        part = slice(b * size, (b + 1) * size)
        inside = (tt >= t[part][0]) & (tt <= t[part][-1])
        assert yy[inside].min() == y[part].min() and yy[inside].max() == y[part].max()
        assert tt[inside][0] == t[part][0] and tt[inside][-1] == t[part][-1]
    assert tt[-1] == t[-1]  # the remainder after the last whole bucket is kept


def test_the_zoom_of_a_long_record_stays_a_zoom():
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from servoid.data import Experiment
    from servoid.models import PolynomialModel
    from servoid.validate import validate
    from servoid.validate._figures import _zoom

    rng = np.random.default_rng(1)
    n = 400_000
    u = rng.standard_normal(n)
    model = PolynomialModel([1.0, -0.5], [np.array([1.0])], 1, 0.01)
    y = np.asarray(model.simulate(u)) + 0.1 * rng.standard_normal(n)
    report = validate(model, Experiment.from_arrays(0.01, u=u, y=y))
    ax = Figure().add_subplot()
    _zoom(ax, report, "")
    assert ax.get_title().startswith("zoom: 5000 samples")  # not n/20 = 20 000
    short = validate(model, Experiment.from_arrays(0.01, u=u[:20_000], y=y[:20_000]))
    ax = Figure().add_subplot()
    _zoom(ax, short, "")
    assert ax.get_title().startswith("zoom: 999 samples")  # a twentieth of the 19 999 residuals
