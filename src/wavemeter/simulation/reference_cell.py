"""A reference gas cell recorded beside the ports: its transmission over a sweep.

:class:`ReferenceCell` holds the gas's true line centres (the table's centres plus the
table's own error, drawn from its stated uncertainty), the cell's true pressure (its
nominal value plus an error drawn from its stated uncertainty), Voigt line shapes (Doppler
width from the temperature and the molecular mass, a pressure width), an etalon ripple on
the baseline and detector noise.

:func:`simulated_band_lines` makes the lines of a simulated linear-molecule band (P and R
branches, Boltzmann strengths); the ``"hcn-like"`` preset uses constants of the order of
the H13C14N 2nu3 band's, but its lines are **not** that band's lines: they are a
simulation and must never be used to calibrate. Real tables: ``ReferenceLines.read_csv``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..exceptions import InputError
from ..reference import ReferenceLines, doppler_sigma_hz, voigt_absorbance
from ..validation import as_rng, check_non_negative, check_positive

__all__ = ["ReferenceCell", "simulated_band_lines", "CELL_PRESETS"]

#: simulated band constants (Hz): origin, first-order spacing, its change per line (the
#: difference of the rotational constants), and the rotational constant for the strengths
CELL_PRESETS = {
    "hcn-like": {
        "origin_hz": 194.363e12,
        "spacing_hz": 85.75e9,
        "spacing_change_hz": -0.586e9,
        "rotational_constant_hz": 43.2e9,
        "max_j": 27,
        "temperature_k": 296.0,
        "mass_u": 28.0,
        "peak_absorbance": 1.0,
        "gamma_hz": 0.5e9,
        "pressure_pa": 13.3e3,
        "pressure_std_pa": 0.4e3,
        "shift_hz_per_pa": -7.0e3,
        "table_std_hz": 5e6,
    },
}

_PLANCK_J_S = 6.62607015e-34
_BOLTZMANN_J_PER_K = 1.380649e-23


def simulated_band_lines(preset: str = "hcn-like") -> tuple[ReferenceLines, np.ndarray]:
    """The table and the relative strengths of a simulated band (see the module docstring).

    Line ``m`` (``m = J + 1`` for R(J), ``-J`` for P(J)) lies at ``origin + spacing m +
    spacing_change m^2``; its strength follows ``|m| exp(-h B J (J + 1) / (k T))`` (lower
    level ``J``); the pressure shift is ``shift (1 + 0.3 cos(m / 4))`` Hz/Pa.

    Returns
    -------
    lines : ReferenceLines
        Labels ``sim R(J)`` / ``sim P(J)``, the preset's table uncertainty, pressure shifts;
        ``source`` says it is simulated.
    strength : ndarray, shape (L,)
        Relative integrated strengths (strongest 1), in the table's order.

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.simulation import simulated_band_lines
    >>> lines, strength = simulated_band_lines()
    >>> len(lines.labels), lines.labels[:2]
    (54, ('sim P(27)', 'sim P(26)'))
    >>> print(f"{lines.center_hz[0] / 1e12:.2f} to {lines.center_hz[-1] / 1e12:.2f} THz")
    191.62 to 196.25 THz
    >>> print(f"strongest {lines.labels[int(np.argmax(strength))]}")
    strongest sim R(8)
    """
    constants = CELL_PRESETS[preset]
    max_j = constants["max_j"]
    m = np.concatenate([-np.arange(max_j, 0, -1), np.arange(1, max_j + 1)])
    lower_j = np.where(m > 0, m - 1, -m)
    labels = [f"sim R({j})" if mm > 0 else f"sim P({j})" for mm, j in zip(m, lower_j, strict=True)]
    center = constants["origin_hz"] + constants["spacing_hz"] * m
    center = center + constants["spacing_change_hz"] * m**2
    energy = _PLANCK_J_S * constants["rotational_constant_hz"] * lower_j * (lower_j + 1)
    strength = np.abs(m) * np.exp(-energy / (_BOLTZMANN_J_PER_K * constants["temperature_k"]))
    lines = ReferenceLines(
        labels=labels,
        center_hz=center,
        std_hz=np.full(m.size, constants["table_std_hz"]),
        pressure_shift_hz_per_pa=constants["shift_hz_per_pa"] * (1 + 0.3 * np.cos(m / 4.0)),
        source=f"SIMULATED {preset} band (wavemeter.simulation): not a standard, never "
        "calibrate with it",
    )
    order = np.argsort(center)
    return lines, strength[order] / strength.max()


@dataclass(frozen=True)
class ReferenceCell:
    """A simulated gas cell; :meth:`transmission` records it over a sweep.

    Parameters
    ----------
    lines : ReferenceLines
        The table a user has for the cell (zero-pressure centres with pressure shifts, or
        centres at the cell's conditions).
    true_center_hz : array_like, shape (L,)
        The gas's true centres, in the table's sense (zero pressure where it has shifts).
    area_hz : array_like, shape (L,)
        Integrated absorbance of each line (Hz).
    sigma_hz, gamma_hz : array_like, shape (L,)
        Doppler standard deviation and pressure half width (Hz) of each line.
    pressure_pa : float
        The cell's true pressure (Pa).
    nominal_pressure_pa, pressure_std_pa : float
        What the user knows of the pressure: a value and its standard uncertainty (Pa).
    ripple : float
        Relative amplitude of an etalon fringe on the baseline.
    ripple_period_hz, ripple_phase_rad : float
        Its period (Hz) and phase.
    noise_std : float
        Detector noise, relative to the baseline (transmission units, rms).

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.simulation import ReferenceCell
    >>> cell = ReferenceCell.simulated(rng=1)
    >>> len(cell.lines.labels)
    54
    >>> line_hz = cell.lines.center_hz[20]
    >>> f_hz = line_hz + np.array([-20e9, 0.0])  # off the line, on it
    >>> print(np.round(cell.transmission(f_hz, rng=2), 2))  # the line absorbs
    [1.   0.43]
    """

    lines: ReferenceLines
    true_center_hz: np.ndarray
    area_hz: np.ndarray
    sigma_hz: np.ndarray
    gamma_hz: np.ndarray
    pressure_pa: float
    nominal_pressure_pa: float
    pressure_std_pa: float
    ripple: float = 0.0
    ripple_period_hz: float = 30e9
    ripple_phase_rad: float = 0.0
    noise_std: float = 1e-3
    _shift: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        count = len(self.lines)
        for name in ("true_center_hz", "area_hz", "sigma_hz", "gamma_hz"):
            array = np.asarray(getattr(self, name), dtype=float).reshape(-1)
            if array.shape != (count,) or not np.all(np.isfinite(array)):
                raise InputError(f"{name} must have one finite value per line ({count})")
            object.__setattr__(self, name, array)
        check_positive("pressure_pa", self.pressure_pa)
        check_non_negative("noise_std", self.noise_std)
        check_non_negative("ripple", self.ripple)
        shift = self.lines.pressure_shift_hz_per_pa
        object.__setattr__(self, "_shift", np.zeros(count) if shift is None else shift)

    @classmethod
    def simulated(
        cls,
        preset: str = "hcn-like",
        *,
        rng=None,
        noise_std: float = 1e-3,
        ripple: float = 2e-3,
        ripple_period_hz: float = 30e9,
    ) -> ReferenceCell:
        """A cell of a simulated band (:func:`simulated_band_lines`) whose true centres and
        pressure are drawn from the table's and the pressure's stated uncertainties.

        Parameters
        ----------
        preset : str
            A key of :data:`CELL_PRESETS`.
        rng : None, int or numpy.random.Generator
            Source of the table errors, the pressure error and the ripple phase.
        noise_std, ripple, ripple_period_hz : float
            As for the class.
        """
        constants = CELL_PRESETS[preset]
        generator = as_rng(rng)
        lines, strength = simulated_band_lines(preset)
        true_center = lines.center_hz + generator.normal(0.0, lines.std_hz)
        pressure = constants["pressure_pa"] + generator.normal(0.0, constants["pressure_std_pa"])
        sigma = doppler_sigma_hz(lines.center_hz, constants["temperature_k"], constants["mass_u"])
        gamma = np.full(len(lines), constants["gamma_hz"])
        peak = voigt_absorbance(0.0, 1.0, sigma[0], gamma[0])
        return cls(
            lines=lines,
            true_center_hz=true_center,
            area_hz=constants["peak_absorbance"] * strength / peak,
            sigma_hz=sigma,
            gamma_hz=gamma,
            pressure_pa=pressure,
            nominal_pressure_pa=constants["pressure_pa"],
            pressure_std_pa=constants["pressure_std_pa"],
            ripple=ripple,
            ripple_period_hz=ripple_period_hz,
            ripple_phase_rad=float(generator.uniform(0, 2 * np.pi)),
            noise_std=noise_std,
        )

    def line_centers_hz(self) -> np.ndarray:
        """The lines' true centres in this cell (Hz): shifted by its true pressure."""
        return self.true_center_hz + self._shift * self.pressure_pa

    def absorbance(self, frequency_hz) -> np.ndarray:
        """Total absorbance of the gas at frequencies (Hz), shape of the input."""
        frequency = np.asarray(frequency_hz, dtype=float)
        total = np.zeros(frequency.shape)
        for k, center in enumerate(self.line_centers_hz()):
            total += voigt_absorbance(
                frequency - center, self.area_hz[k], self.sigma_hz[k], self.gamma_hz[k]
            )
        return total

    def transmission(self, frequency_hz, rng=None) -> np.ndarray:
        """Detector reading behind the cell at frequencies (Hz): baseline (1 plus the etalon
        ripple) times the gas transmission, plus white noise; relative units, shape (N,)."""
        frequency = np.asarray(frequency_hz, dtype=float)
        phase = 2 * np.pi * frequency / self.ripple_period_hz + self.ripple_phase_rad
        baseline = 1.0 + self.ripple * np.sin(phase)
        clean = baseline * np.exp(-self.absorbance(frequency))
        return clean + as_rng(rng).normal(0.0, self.noise_std, frequency.shape)
