"""The method list: one line per method, each module imported only when its method is asked for."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from servoid import OptionError
from servoid.workflows import get_method, method_names
from servoid.workflows._methods import METHODS


def test_each_listed_line_agrees_with_its_method():
    assert method_names() == tuple(METHODS)
    for name in METHODS:
        method = METHODS[name]
        assert method.name == name
        assert METHODS.summary(name) == method.summary, name


def test_an_unknown_name_lists_the_methods():
    with pytest.raises(OptionError, match=r"method must be one of 'arx', 'oe'.*'greybox', 'closedloop', "
                       r"'pneumatic-multistep', 'inverse-dynamics', 'ema'; got 'ox'"):
        get_method("ox")
    with pytest.raises(KeyError):
        METHODS["ox"]


def test_asking_for_one_method_imports_only_its_module():
    code = textwrap.dedent("""
        import sys
        from servoid.workflows import get_method
        get_method("oe")
        print(sorted(m for m in sys.modules if m.startswith("servoid.workflows._")))
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, check=True)
    loaded = set(eval(done.stdout.strip().splitlines()[-1]))  # noqa: S307 — printed above
    assert "servoid.workflows._pem" in loaded
    assert not loaded & {"servoid.plants.ehsa._workflow", "servoid.plants.pneumatic._workflow",
                         "servoid.workflows._narx", "servoid.workflows._greybox",
                         "servoid.plants.ehsa._demo"}
