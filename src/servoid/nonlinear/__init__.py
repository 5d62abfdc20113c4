"""Nonlinear black-box models: polynomial NARX and block-oriented models.

Each model here simulates itself on a record (``replay``), so
:func:`servoid.validate.validate`, ``compare`` and the workflows' validation
records treat it as they treat a linear model.
"""

# NARX
# (exports added by the NARX modules)

# Block-oriented
# (exports added by the block-oriented modules)

__all__: list[str] = []
