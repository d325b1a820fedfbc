"""The Allan family of a laser's fractional frequency, with Greenhall's confidence
intervals.

The fractional frequency is ``(nu - nu0) / nu0``, ``nu0`` the mean reading, bridged
readings included: ``allantools.oadev``, ``mdev`` and ``ohdev`` (the overlapping Hadamard
deviation; same expectation as ``hdev``, tighter) at octave averaging times ``tau = 2^j /
rate`` with at least ``MIN_AVERAGES`` record lengths ``T / tau``; confidence intervals from
Greenhall's equivalent degrees of freedom (``allantools.edf_greenhall``,
``confidence_interval``) for the noise type the fitted model says dominates at each ``tau``
(:func:`~wavemeter.analysis.power_law.deviation_variances`).
"""

from __future__ import annotations

import numpy as np

from .power_law import deviation_variances

#: fewest record lengths T / tau at an averaging time of the Allan family
MIN_AVERAGES = 10
#: Allan-family noise types (allantools' alpha) of white, flicker, random-walk FM, drift
_ALPHAS = (0, -1, -2, -2)


def allan_family(
    series: np.ndarray,
    center_hz: float,
    rate_hz: float,
    levels: np.ndarray,
    drift_hz_per_s: float,
    confidence: float,
) -> dict[str, np.ndarray]:
    """Overlapping Allan, modified Allan and overlapping Hadamard deviations of the
    fractional frequency ``(series - center_hz) / center_hz`` of ``series`` (N,) (Hz) at
    ``rate_hz`` (Hz), with their confidence intervals at ``confidence`` for the noise type
    that ``levels`` (3,) (``h0, h_-1, h_-2`` of the readings) and ``drift_hz_per_s`` say
    dominates: ``taus_s``, ``n_averages`` (M,), ``adev``, ``mdev``, ``hdev`` (M,) and
    ``adev_ci``, ``mdev_ci``, ``hdev_ci`` (2, M)."""
    import allantools

    fractional = (series - center_hz) / center_hz
    samples = fractional.size
    factors = 2 ** np.arange(int(np.log2(samples // MIN_AVERAGES)) + 1)
    taus = factors / rate_hz
    # the noise type that dominates each variance at each tau sets its degrees of freedom
    dominant = deviation_variances(taus, np.maximum(levels, 0.0), drift_hz_per_s, None)
    result = {"taus_s": taus, "n_averages": samples // factors}
    statistics = (
        ("adev", allantools.oadev, 2, False),
        ("mdev", allantools.mdev, 2, True),
        ("hdev", allantools.ohdev, 3, False),
    )
    for name, statistic, order, modified in statistics:
        _, deviation, _, _ = statistic(fractional, rate=rate_hz, data_type="freq", taus=taus)
        alphas = np.array(_ALPHAS)[np.argmax(dominant[name], axis=0)]
        interval = [
            allantools.confidence_interval(
                value,
                allantools.edf_greenhall(
                    alpha=int(alpha),
                    d=order,
                    m=int(m),
                    N=samples + 1,
                    overlapping=True,
                    modified=modified,
                ),
                ci=confidence,
            )
            for value, alpha, m in zip(deviation, alphas, factors, strict=True)
        ]
        result[name] = np.asarray(deviation, dtype=float)
        result[f"{name}_ci"] = np.array(interval, dtype=float).T
    return result
