"""What the learned family declares for its report: the comparison, fringes and samples.

:class:`LearnedReportMixin` gives :class:`~wavemeter.calibration.methods.learned.Calibrator`
and its thermal subclass the declarations a report asks for: the method it is compared
with (the conventional one, by its file tag), the sweep's fringes under the learned map
and the object-space samples of readings.
"""

from __future__ import annotations

import numpy as np

from ...model.cone import delay_phase_rad
from ..files.registry import calibrator_class
from .figures import MapSamplesMixin, fringe_panel, near

__all__ = ["LearnedReportMixin"]


class LearnedReportMixin(MapSamplesMixin):
    """Report declarations of one learned cone map (module docstring)."""

    def comparison(self, port_phases_rad=None):
        """The conventional method (Todd's ideal projection) with the design FSR."""
        return calibrator_class("conventional")(fsr_hz=self.fsr_hz, port_phases_rad=port_phases_rad)

    def _drawn_frequency_hz(self, frequency_hz, temperature_k) -> tuple[np.ndarray, str]:
        """Where sweep readings are drawn (Hz), and what that means (empty: at their own
        frequency)."""
        return frequency_hz, ""

    def fringe_panels(self, frequency_hz, powers_w, monitor_w=None, temperature_k=None):
        """The sweep within ``FRINGE_HALF_WIDTH_FSR`` of the centre under the learned map.

        A model whose phase follows the chip temperature draws each reading at the
        frequency whose phase at the reference temperature is the reading's model phase,
        so that readings of every temperature lie on the one fringe drawn."""
        frequency = np.asarray(frequency_hz, dtype=float)
        rows = near(frequency, self.center_hz_, self.fsr_hz_)
        temperature = None if temperature_k is None else np.asarray(temperature_k)[rows]
        drawn, title = self._drawn_frequency_hz(frequency[rows], temperature)
        panel = fringe_panel(
            self.map_,
            self.center_hz_,
            lambda at_hz: delay_phase_rad(at_hz, self.center_hz_, self.delay_s_),
            drawn,
            np.asarray(powers_w, dtype=float)[rows],
            monitor_w=None if monitor_w is None else np.asarray(monitor_w, dtype=float)[rows],
            noise_std_w=self.noise_std_w_,
            title=title,
        )
        return (panel,)
