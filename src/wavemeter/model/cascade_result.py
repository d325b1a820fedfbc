"""What :func:`~wavemeter.model.cascade_design.design_cascade` returns: a cascade design.

:class:`CascadeDesign` holds the stages' FSRs, their noise, each hand-over's margin and
rate, the coarsest stage's wrap rate and the total, with the inputs they are for; it gives
them as JSON-ready values (:meth:`CascadeDesign.to_dict`) and as an aligned table
(``str``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

__all__ = ["CascadeDesign"]


@dataclass(frozen=True)
class CascadeDesign:
    """A cascade of ideal stages chosen by :func:`design_cascade`.

    Attributes
    ----------
    fsrs_hz : tuple of float, shape (K,)
        Stage FSRs (Hz), coarsest first; the last is ``finest_fsr_hz`` exactly.
    wrong_order_rate : float
        Predicted probability per reading that some stage's order is wrong (the coarsest
        stage wraps or a hand-over picks the wrong order).
    handover_margins : tuple of float, shape (K - 1,)
        Margin of each hand-over ``k -> k+1``: half the finer FSR over the residual's
        standard deviation (standard deviations).
    handover_rates : tuple of float, shape (K - 1,)
        Wrong-order rate of each hand-over (per reading).
    ratios : tuple of float, shape (K - 1,)
        ``F_k / F_{k+1}`` of each hand-over (all equal).
    stage_std_hz : tuple of float, shape (K,)
        Frequency standard deviation of each stage at its share of the power (Hz): the
        ideal bound times ``noise_factor``.
    edge_margin : float
        How far the coarsest stage's unique range reaches beyond each end of the band, in
        that stage's standard deviations: ``(F_0 - B) / (2 s_0)``.
    edge_rate : float
        Wrap rate of the coarsest stage, averaged over readings uniform over the band.
    band_hz : (float, float) or None
        The band (Hz, low and high); None when only its width was given.
    band_width_hz : float
        Width ``B`` of the band (Hz).
    ports : int
        Ports per stage.
    power_w : float
        Source power entering the cascade (W); each stage receives ``power_w / K``.
    noise_w : float
        Detector noise standard deviation per port and reading (W).
    requested_rate : float
        The wrong-order rate asked for (per reading).
    noise_factor : float
        The stages' noise over the ideal bound the design allows for.
    fsr_tolerance : float
        The relative error of every FSR the design allows for: margins and rates are
        those of the worst case (item 8 of :mod:`wavemeter.model.cascade_design`).

    Examples
    --------
    >>> import wavemeter as wm
    >>> design = wm.design_cascade((191e12, 196e12), 50e9)  # the C band, read to a 50 GHz fringe
    >>> design.stages
    3
    >>> print([f"{fsr / 1e9:.0f} GHz" for fsr in design.fsrs_hz])
    ['5999 GHz', '548 GHz', '50 GHz']
    >>> print([f"{std / 1e6:.0f} MHz" for std in design.stage_std_hz])  # each stage's noise
    ['7016 MHz', '641 MHz', '58 MHz']
    >>> print([f"{margin:.1f}" for margin in design.handover_margins])  # in standard deviations
    ['31.8', '31.8']
    >>> design.wrong_order_rate <= design.requested_rate
    True
    """

    fsrs_hz: tuple[float, ...]
    wrong_order_rate: float
    handover_margins: tuple[float, ...]
    handover_rates: tuple[float, ...]
    ratios: tuple[float, ...]
    stage_std_hz: tuple[float, ...]
    edge_margin: float
    edge_rate: float
    band_hz: tuple[float, float] | None
    band_width_hz: float
    ports: int
    power_w: float
    noise_w: float
    requested_rate: float
    noise_factor: float = 1.0
    fsr_tolerance: float = 0.0

    @property
    def stages(self) -> int:
        """Number of stages ``K``."""
        return len(self.fsrs_hz)

    @property
    def stage_power_w(self) -> float:
        """Power each stage receives (W): ``power_w / K``."""
        return self.power_w / self.stages

    @property
    def meets_rate(self) -> bool:
        """Whether the predicted wrong-order rate is at most the requested one."""
        return self.wrong_order_rate <= self.requested_rate

    def to_dict(self) -> dict:
        """The design as plain JSON-ready values, units in the key names, plus
        ``stages``, ``stage_power_w`` and ``meets_rate``."""
        values = {
            name: list(value) if isinstance(value, tuple) else value
            for name, value in asdict(self).items()
        }
        return {
            **values,
            "stages": self.stages,
            "stage_power_w": self.stage_power_w,
            "meets_rate": self.meets_rate,
        }

    def __str__(self) -> str:
        """An aligned table: one row per stage (FSR, ratio to the next, stage std, margin
        and rate of its hand-over to the next), then the wrap and total rates."""
        header = ("stage", "FSR GHz", "ratio", "std MHz", "margin (std)", "hand-over rate")
        rows = []
        for index, (fsr, std) in enumerate(zip(self.fsrs_hz, self.stage_std_hz, strict=True)):
            handover = index < self.stages - 1
            rows.append(
                (
                    str(index + 1),
                    f"{fsr / 1e9:.6g}",
                    f"{self.ratios[index]:.4g}" if handover else "-",
                    f"{std / 1e6:.5g}",
                    f"{self.handover_margins[index]:.2f}" if handover else "-",
                    _rate_text(self.handover_rates[index]) if handover else "-",
                )
            )
        widths = [max(len(row[column]) for row in (header, *rows)) for column in range(6)]
        lines = [
            "  ".join(cell.rjust(width) for cell, width in zip(row, widths, strict=True))
            for row in (header, *rows)
        ]
        band = (
            f"{self.band_hz[0] / 1e12:.6g}-{self.band_hz[1] / 1e12:.6g} THz, "
            if self.band_hz is not None
            else ""
        )
        lines += [
            f"band: {band}{self.band_width_hz / 1e9:.6g} GHz wide; stage 1's range reaches "
            f"{self.edge_margin:.2f} std beyond each end: wrap rate {_rate_text(self.edge_rate)}",
            f"{self.stages} stage(s) of {self.ports} ports, each {self.stage_power_w:.4g} W "
            f"(source {self.power_w:.4g} W), detector noise {self.noise_w:.4g} W per port; "
            f"stages {self.noise_factor:g}x the ideal noise, FSRs within "
            f"{100 * self.fsr_tolerance:g} % (margins and rates at the worst)",
            f"wrong-order rate per reading: {_rate_text(self.wrong_order_rate)} predicted "
            f"({_rate_text(self.requested_rate)} requested)",
        ]
        return "\n".join(lines)


def _rate_text(rate: float) -> str:
    """A rate with 3 digits; one too small for a double is shown as ``< 1e-300``."""
    return f"{rate:.3g}" if rate > 1e-300 else "< 1e-300"
