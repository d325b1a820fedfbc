"""What a simulated scenario takes unless told otherwise: the source power and noise, the
span, the cascade's band, the laser's rate, and the streams its seed is split into.

Random streams: the device's Table 1 impairments are drawn from the seed; the spectral
slopes from ``default_rng([seed, SPECTRAL_STREAM])``; the power drift from ``[seed,
DRIFT_STREAM]``; the noise (test frequencies, test temperatures, power fluctuation,
detector noise, in that order) from the seed, or, at a temperature or ramp given, from
``[seed, TEMPERATURE_STREAM, *temperatures in mK]``; the laser record from ``[seed,
LASER_STREAM]``, the dark readings from ``[seed, DARK_STREAM]``. A power drift, a laser record
or dark readings leave the other draws as they were; test
readings are drawn before the sweep's noise, so a sweep recorded with them has other noise
than one without (as ``wavemeter simulate`` has always drawn it).
"""

from __future__ import annotations

__all__ = [
    "DEFAULT_POWER_W",
    "DEFAULT_NOISE_W",
    "DEFAULT_SPAN_FSR",
    "DEFAULT_CASCADE_BAND_HZ",
    "DEFAULT_LASER_RATE_HZ",
    "DEFAULT_THERMAL_RAD_PER_K",
    "DRIFT_STREAM",
    "TEMPERATURE_STREAM",
    "SPECTRAL_STREAM",
    "LASER_STREAM",
    "DARK_STREAM",
]

#: source power (W) and detector noise std per reading (W) unless given
DEFAULT_POWER_W = 1e-3
DEFAULT_NOISE_W = 5e-7
#: sweep span of a single device unless given (FSRs)
DEFAULT_SPAN_FSR = 1.0
#: the band a cascade is swept over unless given: the C band (Hz)
DEFAULT_CASCADE_BAND_HZ = (191.0e12, 195.4e12)
#: sample rate of the laser record unless given (Hz)
DEFAULT_LASER_RATE_HZ = 10e6
#: bias phase change per kelvin of a thermal drift for a device without a thermal
#: coefficient (a Table 1 device has none)
DEFAULT_THERMAL_RAD_PER_K = 1.0
#: streams of the seed: the power drift, the noise at a given temperature, the spectral
#: slopes (the seed itself would draw them from the numbers of the Table 1 spread), the laser
DRIFT_STREAM = 1
TEMPERATURE_STREAM = 2
SPECTRAL_STREAM = 3
LASER_STREAM = 4
DARK_STREAM = 5
