"""A cascade of interferometers of decreasing FSR fed by one input: an absolute meter.

One source is split (power shares ``split``) into several stages, each an
:class:`~wavemeter.simulation.interferometer.Interferometer`; a reading holds every stage's
ports side by side. The coarsest stage's FSR exceeds the band, so its phase is unique
there; each stage then picks the fringe order of the next (commercial multi-etalon meters
work this way, see :class:`~wavemeter.calibration.methods.cascade.CascadeCalibrator`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..exceptions import InputError, shown
from ..validation import as_rng
from .interferometer import DEFAULT_CENTER_HZ, Interferometer
from .spectral_presets import SPECTRAL_PRESETS

__all__ = ["CascadeInterferometer", "ISSUE_CASCADE_FSRS_HZ"]

#: the C-band cascade of the issue (Hz, coarsest first): 5 THz covers the band
ISSUE_CASCADE_FSRS_HZ = (5e12, 500e9, 50e9)


def _stage_ports(ports, stages: int) -> tuple[int, ...]:
    counts = (ports,) * stages if np.ndim(ports) == 0 else tuple(ports)
    if len(counts) != stages or not all(
        isinstance(count, (int, np.integer)) and not isinstance(count, bool) and count >= 3
        for count in counts
    ):
        raise InputError(
            f"ports must be an integer >= 3 or one per stage ({stages}), got {ports!r}",
            parameter="ports",
        )
    return tuple(int(count) for count in counts)


@dataclass(frozen=True)
class CascadeInterferometer:
    """Interferometer stages fed by one source through a splitter.

    Parameters
    ----------
    stages : sequence of Interferometer
        The stages, coarsest FSR first; they share one ``center_hz``.
    split : None or array_like, shape (K,)
        Share of the source power each stage receives (positive, sum at most 1, the rest
        lost in the splitter); None: equal shares ``1 / K``. Stored read-only.

    Notes
    -----
    A reading's columns are stage 1's ports, then stage 2's, ... (:attr:`stage_ports`).

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> meter = wm.CascadeInterferometer.table1(fsrs_hz=(5e12, 500e9, 50e9), seed=2)
    >>> meter.stage_ports
    ((0, 1, 2), (3, 4, 5), (6, 7, 8))
    >>> powers = meter.powers(np.array([193.4e12, 193.41e12]), power_w=1e-3)
    >>> powers.shape  # each reading: stage 1's ports, then stage 2's, then stage 3's
    (2, 9)
    """

    stages: tuple[Interferometer, ...]
    split: np.ndarray | None = None

    def __post_init__(self):
        stages = tuple(self.stages)
        if not stages or not all(isinstance(stage, Interferometer) for stage in stages):
            raise InputError(
                "stages must be a non-empty sequence of Interferometer", parameter="stages"
            )
        centers = {stage.center_hz for stage in stages}
        if len(centers) != 1:
            raise InputError(
                f"stages must share one center_hz (the phase origin), got {sorted(centers)} Hz",
                parameter="stages",
            )
        split = np.full(len(stages), 1.0 / len(stages)) if self.split is None else self.split
        split = np.array(split, dtype=float)
        if (
            split.shape != (len(stages),)
            or not np.all(np.isfinite(split) & (split > 0))
            or split.sum() > 1.0 + 1e-12
        ):
            raise InputError(
                f"split must be {len(stages)} positive power shares summing to at most 1, "
                f"got {self.split!r}",
                parameter="split",
            )
        split.setflags(write=False)
        object.__setattr__(self, "stages", stages)
        object.__setattr__(self, "split", split)

    @classmethod
    def table1(
        cls,
        fsrs_hz=ISSUE_CASCADE_FSRS_HZ,
        ports=3,
        seed=None,
        *,
        center_hz: float = DEFAULT_CENTER_HZ,
        spectral: str | None = "sin",
        split=None,
    ) -> CascadeInterferometer:
        """A cascade of Table 1 devices with independent impairments and wide-band effects.

        Stage ``k`` is :meth:`Interferometer.table1` at ``fsrs_hz[k]`` drawn from its own
        stream of ``seed``, then (``spectral`` not None) given the platform's spectral
        slopes from another stream and its dispersion scaled to the stage's delay: the
        dispersion ``beta_2 L`` of a delay line grows with its length, and the preset's is
        that of ``reference_delay_s``.

        Parameters
        ----------
        fsrs_hz : sequence of float
            Design FSR of each stage (Hz), coarsest first.
        ports : int or sequence of int
            Ports of every stage, or of each.
        seed : None, int or numpy.random.Generator
            Source of every draw.
        center_hz : float
            Centre frequency of every stage (Hz).
        spectral : None or str
            A key of :data:`~wavemeter.simulation.SPECTRAL_PRESETS`; None: no dispersion or
            spectral slopes.
        split : None or array_like, shape (K,)
            Power shares of the stages (None: equal).

        Returns
        -------
        CascadeInterferometer
        """
        fsrs = np.atleast_1d(np.asarray(fsrs_hz, dtype=float))
        if fsrs.ndim != 1 or fsrs.size == 0 or not np.all(np.isfinite(fsrs) & (fsrs > 0)):
            raise InputError(
                f"fsrs_hz must be one or more positive FSRs (Hz), got {shown(fsrs_hz)}",
                parameter="fsrs_hz",
            )
        if spectral is not None and spectral not in SPECTRAL_PRESETS:
            raise InputError(
                f"spectral must be None or one of {tuple(SPECTRAL_PRESETS)}, got {spectral!r}",
                parameter="spectral",
            )
        counts = _stage_ports(ports, fsrs.size)
        # one stream per stage for the static draw, one for the spectral slopes
        streams = [
            np.random.default_rng(value) for value in as_rng(seed).integers(0, 2**63, 2 * fsrs.size)
        ]
        stages = []
        for index, (fsr, count) in enumerate(zip(fsrs, counts, strict=True)):
            stage = Interferometer.table1(
                count, seed=streams[2 * index], fsr_hz=float(fsr), center_hz=center_hz
            )
            if spectral is not None:
                preset = SPECTRAL_PRESETS[spectral]
                scaled = replace(
                    preset,
                    dispersion_s2=preset.dispersion_s2 * stage.delay_s / preset.reference_delay_s,
                )
                stage = stage.with_spectral(scaled, seed=streams[2 * index + 1])
            stages.append(stage)
        return cls(tuple(stages), split=split)

    @property
    def ports(self) -> int:
        """Columns of a reading: every stage's ports."""
        return sum(stage.ports for stage in self.stages)

    @property
    def stage_ports(self) -> tuple[tuple[int, ...], ...]:
        """The reading columns (zero-based) of each stage."""
        edges = np.cumsum([0] + [stage.ports for stage in self.stages])
        return tuple(
            tuple(range(int(low), int(high)))
            for low, high in zip(edges[:-1], edges[1:], strict=True)
        )

    @property
    def center_hz(self) -> float:
        """The stages' common centre frequency (Hz)."""
        return self.stages[0].center_hz

    @property
    def true_fsrs_hz(self) -> tuple[float, ...]:
        """Each stage's FSR at ``center_hz`` (Hz), coarsest first."""
        return tuple(stage.true_fsr_hz for stage in self.stages)

    def powers(self, f_hz, power_w=1e-3, noise_w=0.0, rng=None, temperature_k=None) -> np.ndarray:
        """Port readings (W) of every stage for source frequencies ``f_hz``.

        Parameters
        ----------
        f_hz : array_like, shape (N,)
            Source optical frequency (Hz).
        power_w : float or array_like, shape (N,)
            Source power (W) before the split.
        noise_w : float or array_like, shape (sum of ports,)
            Detector noise standard deviation per reading (W), one for every column or one
            per column.
        rng : None, int or numpy.random.Generator
            Source of the noise.
        temperature_k : None, float or array_like, shape (N,)
            Chip temperature (K), as :meth:`Interferometer.powers` takes it.

        Returns
        -------
        ndarray, shape (N, sum of ports), W
        """
        noise = np.asarray(noise_w, dtype=float)
        if noise.shape not in ((), (self.ports,)):
            raise InputError(
                f"noise_w must be a number (W) or {self.ports} of them, got shape {noise.shape}",
                parameter="noise_w",
            )
        generator = as_rng(rng)
        power = np.asarray(power_w, dtype=float)
        blocks = [
            stage.powers(
                f_hz,
                power * share,
                noise if noise.ndim == 0 else noise[list(columns)],
                rng=generator,
                temperature_k=temperature_k,
            )
            for stage, share, columns in zip(self.stages, self.split, self.stage_ports, strict=True)
        ]
        return np.concatenate(blocks, axis=1)
