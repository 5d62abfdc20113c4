"""Nonlinear black-box models: polynomial NARX, block-oriented and PNLSS models.

Each model here simulates itself on a record (``replay``), so
:func:`servoid.validate.validate`, ``compare`` and the workflows' validation
records treat it as they treat a linear model.
"""

# NARX
from ._narx import MAX_CANDIDATES, candidate_terms, fit_narx
from ._narx_model import NarxModel

# Polynomial nonlinear state space
# isort: split
from ._pnlss import MONOMIALS, PnlssModel
from ._pnlss_fit import fit_pnlss

# Block-oriented
# isort: split
from ._block import BlockModel
from ._block_fit import fit_block, fit_hammerstein, fit_hammerstein_wiener, fit_wiener
from ._static import (
    SHAPES,
    AbsoluteValue,
    DeadZone,
    PiecewiseLinear,
    Polynomial,
    Saturation,
    SignedPower,
    StaticFunction,
    StaticNonlinearity,
)

# isort: split
# A building block the workflows import (through this package, not its modules); not in __all__.
from ._block_retry import fit_block_retrying as fit_block_retrying

__all__: list[str] = [
    "MAX_CANDIDATES",
    "MONOMIALS",
    "SHAPES",
    "AbsoluteValue",
    "BlockModel",
    "DeadZone",
    "NarxModel",
    "PiecewiseLinear",
    "PnlssModel",
    "Polynomial",
    "Saturation",
    "SignedPower",
    "StaticFunction",
    "StaticNonlinearity",
    "candidate_terms",
    "fit_block",
    "fit_hammerstein",
    "fit_hammerstein_wiener",
    "fit_narx",
    "fit_pnlss",
    "fit_wiener",
]
