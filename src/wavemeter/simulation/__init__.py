"""Simulated interferometers with the impairments of the paper's Table 1."""

from .interferometer import Interferometer

__all__ = ["Interferometer"]
