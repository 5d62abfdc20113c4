"""The record every actuator of servoid fills in: :class:`Plant`.

An actuator lives in one subpackage, ``servoid.plants.<name>``, holding its
physics (parameter sets with units and sources), its compiled right-hand
side and simulator (stepped by :func:`servoid.integrate.rk4_step`), its
loop (the controller it runs in), its virtual bench (the files a rig
writes), its physical identification and the workflow that the experiment
file names.  The subpackage's ``__init__`` exports one ``PLANT`` record;
registering the actuator is one line in :data:`servoid.plants.PLANTS`.

The record names its parts by ``"module:attribute"``: listing the plants,
their methods or their benches imports none of them, and a part loads on
first use (:meth:`Plant.load`).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from .._errors import OptionError, OptionTypeError

__all__ = ["PARTS", "Plant"]

#: The parts a plant may name, with what each must be.
PARTS: dict[str, str] = {
    "parameters": "a mapping of named, documented parameter sets (name → frozen dataclass)",
    "rhs": "the compiled right-hand side rhs(t, x, w, ctx) its simulator steps",
    "simulate": "simulate(params, reference, dt, **options) → a response: the plant in its loop",
    "loop": "the type of the controller or loop the plant runs in",
    "bench": "write_bench(out, **options) → the rig files, experiment file and truth it wrote",
    "fleet": "write_fleet(out, **options) → a virtual fleet of units (or none)",
    "methods": "a tuple of workflow Methods: the plant's physical identification",
    "cli": "add_cli(subcommands, json_flag) → adds its `servoid bench …` commands (argparse only)",
    "limits": "plan_test(set_name, excitation, unit) → the planned test against the actuator's "
              "limits (.feasible, .note(), .to_dict()), for `servoid excite --plant`",
}


#: Parts a plant may leave out.
_OPTIONAL = frozenset({"bench", "fleet", "cli", "limits"})


@dataclass(frozen=True)
class Plant:
    """One actuator: physics, right-hand side, loop, bench, identify.

    Attributes
    ----------
    name : str
        Short name (``"ehsa"``), the subpackage's name and the
        ``servoid bench`` command's.
    title : str
        What it is, in words ("electro-hydraulic servo actuator").
    methods : mapping
        The ``[identify] method`` names it registers, each with its one-line
        summary (listed by ``servoid methods`` without importing the plant).
    parts : mapping
        :data:`PARTS` name → ``"module:attribute"``; ``bench`` and ``fleet``
        may be absent (an actuator known from real records only).
    """

    name: str
    title: str
    methods: dict[str, str]
    parts: dict[str, str]

    def __post_init__(self) -> None:
        # plain checks, not servoid._checks (which loads numpy): the records are built when
        # servoid.plants is imported, and the command line's parser lists them (servoid --help)
        for name in ("name", "title"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name):
                raise _type_error(name, getattr(self, name), "a non-empty string")
        if not isinstance(self.methods, dict) or not all(
                isinstance(k, str) and isinstance(v, str) for k, v in self.methods.items()):
            raise _type_error("methods", self.methods, "a dict of method name → summary")
        missing = sorted(set(PARTS) - _OPTIONAL - set(self.parts))
        unknown = sorted(set(self.parts) - set(PARTS))
        if missing or unknown:
            raise OptionError(f"plant {self.name!r}: parts missing {missing}, unknown {unknown}; "
                              f"a plant names {', '.join(PARTS)}")
        for part, ref in self.parts.items():
            if not isinstance(ref, str) or ref.count(":") != 1:
                raise _type_error(f"parts[{part!r}]", ref, '"module:attribute"')

    def load(self, part: str) -> Any:
        """Return one of the plant's parts, importing its module on first use.

        Raises
        ------
        OptionError
            The plant has no such part.
        """
        if part not in self.parts:
            have = ", ".join(sorted(self.parts))
            raise OptionError(f"plant {self.name!r} has no part {part!r}; it has {have}")
        module, _, attribute = self.parts[part].partition(":")
        return getattr(importlib.import_module(module), attribute)


def _type_error(name: str, value: object, expected: str) -> OptionTypeError:
    return OptionTypeError(f"{name} must be {expected}, got {value!r} ({type(value).__name__})")
