"""The cascade simulator: stages fed by one source, their columns side by side."""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.simulation import SPECTRAL_PRESETS, SpectralPreset

FSRS_HZ = (5e12, 500e9, 50e9)


def test_readings_are_each_stage_at_its_share_of_the_power():
    cascade = wm.CascadeInterferometer.table1(
        FSRS_HZ, ports=(3, 4, 3), seed=1, split=(0.2, 0.3, 0.5)
    )
    assert cascade.ports == 10
    assert cascade.stage_ports == ((0, 1, 2), (3, 4, 5, 6), (7, 8, 9))
    f = cascade.center_hz + np.linspace(-2e12, 2e12, 7)
    readings = cascade.powers(f, 2e-3)
    for stage, share, columns in zip(
        cascade.stages, cascade.split, cascade.stage_ports, strict=True
    ):
        np.testing.assert_array_equal(readings[:, list(columns)], stage.powers(f, 2e-3 * share))
    assert cascade.true_fsrs_hz == tuple(stage.true_fsr_hz for stage in cascade.stages)


def test_stages_are_independent_table1_draws_with_scaled_dispersion():
    cascade = wm.CascadeInterferometer.table1(FSRS_HZ, seed=2)
    again = wm.CascadeInterferometer.table1(FSRS_HZ, seed=2)
    preset = SPECTRAL_PRESETS["sin"]
    for stage, twin, fsr in zip(cascade.stages, again.stages, FSRS_HZ, strict=True):
        np.testing.assert_array_equal(stage.output_coupler, twin.output_coupler)
        # the Table 1 delay spread is 5 %
        assert abs(stage.true_fsr_hz / fsr - 1) < 0.25
        # beta_2 L grows with the imbalance: the preset's dispersion is for 20 ps
        assert stage.dispersion_s2 == pytest.approx(
            preset.dispersion_s2 * stage.delay_s / preset.reference_delay_s, rel=1e-15
        )
        assert stage.coupler_slope_per_thz is not None
    couplers = [stage.output_coupler for stage in cascade.stages]
    assert not np.allclose(couplers[0], couplers[2])
    plain = wm.CascadeInterferometer.table1(FSRS_HZ, seed=2, spectral=None)
    assert all(stage.dispersion_s2 == 0 for stage in plain.stages)


def test_noise_is_per_column_and_equal_shares_by_default():
    cascade = wm.CascadeInterferometer.table1(FSRS_HZ, seed=3)
    np.testing.assert_allclose(cascade.split, 1 / 3)
    f = np.full(20_000, cascade.center_hz)
    noise = np.zeros(9)
    noise[4] = 1e-6
    scatter = cascade.powers(f, 1e-3, noise, rng=4).std(axis=0)
    assert scatter[4] == pytest.approx(1e-6, rel=0.05)
    # the other columns carry float rounding of identical readings only
    assert np.all(np.delete(scatter, 4) < 1e-15)


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"fsrs_hz": ()}, "fsrs_hz"),
        ({"fsrs_hz": (5e12, -1.0)}, "fsrs_hz"),
        ({"ports": 2}, "ports"),
        ({"ports": (3, 3)}, "ports"),
        ({"spectral": "glass"}, "spectral"),
        ({"split": (0.5, 0.5, 0.5)}, "split"),
        ({"split": (0.5, 0.5)}, "split"),
    ],
)
def test_bad_settings_are_named(kwargs, parameter):
    with pytest.raises(wm.InputError) as caught:
        wm.CascadeInterferometer.table1(**{"fsrs_hz": FSRS_HZ, **kwargs})
    assert caught.value.parameter == parameter


def test_stages_must_share_a_centre_and_be_interferometers():
    one = wm.Interferometer.ideal(3, fsr_hz=1e12)
    other = wm.Interferometer.ideal(3, fsr_hz=1e11, center_hz=one.center_hz + 1e9)
    with pytest.raises(wm.InputError, match="share one center_hz"):
        wm.CascadeInterferometer((one, other))
    with pytest.raises(wm.InputError, match="sequence of Interferometer"):
        wm.CascadeInterferometer((one, "stage"))
    with pytest.raises(wm.InputError, match="noise_w must be"):
        wm.CascadeInterferometer((one,)).powers([one.center_hz], noise_w=np.ones(4))


def test_a_preset_needs_a_positive_reference_delay():
    with pytest.raises(wm.InputError) as caught:
        SpectralPreset(4e-28, 0.01, 0.002, 0.005, reference_delay_s=0.0)
    assert caught.value.parameter == "reference_delay_s"
