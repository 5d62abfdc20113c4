"""The public surface of servoid.models is pinned."""

from servoid import models


def test_exports_are_pinned_and_sorted():
    assert models.__all__ == sorted(models.__all__)
    for name in models.__all__:
        assert getattr(models, name).__doc__


def test_public_docstring_summaries_are_short_and_end_with_period():
    for name in models.__all__:
        obj = getattr(models, name)
        members = [obj]
        if isinstance(obj, type):
            members += [getattr(obj, k) for k in dir(obj) if not k.startswith("_")]
        for member in members:
            if not (callable(member) or isinstance(member, property)):
                continue
            summary = (member.__doc__ or "").strip().splitlines()[0]
            assert len(summary) < 64 and summary.endswith("."), (name, summary)
