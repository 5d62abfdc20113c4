"""Workflows: end-to-end runs that the command line exposes one to one."""

from ._demo import DemoResult, run_demo
from ._identify import IdentificationResult, identify

__all__ = ["DemoResult", "IdentificationResult", "identify", "run_demo"]
