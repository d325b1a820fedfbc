"""Shared fixtures: seeded randomness and simulated devices."""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm

POWER_W = 1e-3
NOISE_W = 5e-7  # Table 1: 5e-4 mW at 1 mW


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


def random_test_frequencies(device: wm.Interferometer, samples: int, rng) -> np.ndarray:
    """Frequencies (Hz) uniform over one true FSR about the device centre."""
    half = device.true_fsr_hz / 2
    return device.center_hz + rng.uniform(-half, half, samples)
