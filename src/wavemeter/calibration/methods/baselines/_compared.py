"""What every baseline is compared with in its report: the learned calibration."""

from __future__ import annotations

from ...files.registry import calibrator_class

__all__ = ["ComparedWithLearnedMixin"]


class ComparedWithLearnedMixin:
    """``comparison``: the learned calibration with the design FSR (what learning the map
    buys over the baseline)."""

    def comparison(self, port_phases_rad=None):
        return calibrator_class("learned")(fsr_hz=self.fsr_hz)
