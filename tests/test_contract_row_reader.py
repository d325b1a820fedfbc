"""Every calibrator's one-row reader (``row_reader``) against its batch ``readout``.

The live service and ``stream`` read one reading at a time with ``cal.row_reader()``; it
must give what ``readout`` gives the same readings as a block: frequency and standard
deviation to float64 rounding (``RTOL``: the same arithmetic on one reading, in plain floats
or small arrays, rounds differently in the last bits; measured <= 1e-15), every flag bit and
every declared extra. Enrolment follows :mod:`tests.test_contract`: a class per registered
calibrator and case, fitted once on the same simulated sweep. The rows are random test
readings with bad ones among them: NaN cells, no light, negative power, a dim reading (lit
but below the no-light fraction), tenfold power, a reading off the cone, and, for a
calibration that needs per-reading inputs, a non-finite input and a coarse frequency far
outside its band.
"""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm

from . import test_contract as contract

RTOL = 1e-12
ROWS = 120
FLAG = wm.ReadingFlag


def bad_rows(cal, readings, truth_hz, rng):
    """``readings`` (N, n) with bad ones put in, and their per-reading inputs."""
    rows = readings.copy()
    inputs = contract.reading_inputs(cal, truth_hz)
    inputs = {
        name: np.full(len(rows), float(value)) if np.ndim(value) == 0 else value.copy()
        for name, value in inputs.items()
    }
    rows[0, 1] = np.nan
    rows[1] = 0.0
    rows[2] = -rows[2]
    rows[3] *= 0.002  # lit, but below the no-light fraction of the sweep's power
    rows[4] *= 10.0
    rows[5, 0] += 50 * contract.NOISE_W  # far off the cone
    rows[6, -1] = np.inf
    picked = rng.choice(np.arange(10, len(rows)), size=10, replace=False)
    rows[picked] *= rng.uniform(0.3, 3.0, (10, 1))  # some in, some out of the power range
    for name, values in inputs.items():
        values[7] = np.nan
        if name == "coarse_hz":
            values[8] += 3e12  # no map there
            values[9] -= 5e12
    return rows, inputs


class RowReaderContract:
    """``row_reader`` agrees with ``readout`` (module docstring); ``base`` is the contract
    class of :mod:`tests.test_contract` whose fitted calibration it reads with."""

    base = None

    def test_row_reader_agrees_with_readout(self):
        cal, _, test, test_hz = self.base().fitted("table1", contract.NOISE_W)
        rng = np.random.default_rng(29)
        picked = rng.choice(len(test), size=ROWS, replace=False)
        rows, inputs = bad_rows(cal, test[picked], test_hz[picked], rng)
        batch = cal.readout(rows, **inputs)
        read = cal.row_reader()
        records = [
            read(row, **{name: values[k] for name, values in inputs.items()})
            for k, row in enumerate(rows)
        ]
        found = {
            name: np.array([getattr(record, name) for record in records])
            for name in ("frequency_hz", "frequency_std_hz", "flags")
        }
        np.testing.assert_allclose(found["frequency_hz"], batch.frequency_hz, rtol=RTOL)
        np.testing.assert_allclose(found["frequency_std_hz"], batch.frequency_std_hz, rtol=RTOL)
        np.testing.assert_array_equal(found["flags"], batch.flags)
        assert all(set(record.extras) == set(cal.reading_outputs) for record in records)
        for name, values in batch.extras.items():
            np.testing.assert_allclose([r.extras[name] for r in records], values, rtol=RTOL)
        # the bad rows are there, and most readings are read
        assert (batch.flags[[0, 1, 2, 6]] & FLAG.INVALID).all()
        assert batch.flags[4] & FLAG.POWER_RANGE
        assert np.isfinite(batch.frequency_hz).sum() >= ROWS - 20

    def test_row_reader_wants_the_inputs_the_calibration_requires(self):
        cal, _, test, test_hz = self.base().fitted("table1", contract.NOISE_W)
        read = cal.row_reader()
        if not cal.requires:
            assert np.isfinite(read(test[0]).frequency_hz)
            return
        with pytest.raises(wm.InputError, match=sorted(cal.requires)[0]):
            read(test[0])


def _enrol() -> list[str]:
    names = []
    for name in contract.ENROLLED:
        enrolled = f"TestRowReader{name.removeprefix('Test')}"
        base = getattr(contract, name)
        globals()[enrolled] = type(enrolled, (RowReaderContract,), {"base": base})
        names.append(enrolled)
    return names


ENROLLED = _enrol()


def test_every_contract_class_has_a_row_reader_check():
    assert len(ENROLLED) == len(contract.ENROLLED) > 0
