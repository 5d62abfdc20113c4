"""What an identification method is built from, for methods outside this package.

A method lives in the module of its subject (a plant's physical identification lives in
``servoid.plants.<name>``) and is registered by name in ``servoid.workflows``' method list;
everything it needs from the registry comes from here: the :class:`Method` record with its
:class:`Option` s and :class:`TableSchema` s, the option checks, the shared options, the
summary and verdict helpers of the result contract, and the report pieces every method uses.
See ``docs/adding-a-method.md``.
"""

from __future__ import annotations

from ._common import (
    keyed,
    parameter_table,
    read_truth,
    report_options,
    spec_inputs,
    validation_section,
)
from ._options import (
    HORIZON,
    OUTPUT,
    ROLE,
    boolean,
    choice,
    choices,
    integer,
    number,
    optional,
    orders,
    text,
)
from ._registry import FigureWriter, Method, Option, TableSchema
from ._summary import Displayed, ParameterValue, RecordSummary, summary_of
from ._verdict import (
    count_check,
    interval_check,
    loop_verdict,
    record_conditions,
    spec_conditions,
    validation_checks,
)

__all__ = [
    "HORIZON",
    "OUTPUT",
    "ROLE",
    "Displayed",
    "FigureWriter",
    "Method",
    "Option",
    "ParameterValue",
    "RecordSummary",
    "TableSchema",
    "boolean",
    "choice",
    "choices",
    "count_check",
    "integer",
    "interval_check",
    "keyed",
    "loop_verdict",
    "number",
    "optional",
    "orders",
    "parameter_table",
    "read_truth",
    "record_conditions",
    "report_options",
    "spec_conditions",
    "spec_inputs",
    "summary_of",
    "text",
    "validation_checks",
    "validation_section",
]
