"""The steps a fit takes, in order, on a validated sweep (:class:`Sweep`), with the state
it carries from step to step (:class:`FitContext`)."""

from .steps import SweepFitMixin
from .sweep import FitContext, Sweep, checked_sweep

__all__ = ["FitContext", "Sweep", "SweepFitMixin", "checked_sweep"]
