"""Nonlinear black-box models: polynomial NARX and block-oriented models.

Each model here simulates itself on a record (``replay``), so
:func:`servoid.validate.validate`, ``compare`` and the workflows' validation
records treat it as they treat a linear model.
"""

# NARX
from ._narx import MAX_CANDIDATES, candidate_terms, fit_narx
from ._narx_model import NarxModel

__all__: list[str] = [
    "MAX_CANDIDATES",
    "NarxModel",
    "candidate_terms",
    "fit_narx",
]
