"""ReferenceLines: the line table users supply, its CSV round trip and its errors."""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.reference import ReferenceLines
from wavemeter.units import SPEED_OF_LIGHT_M_S


def write(tmp_path, text: str, name="lines.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_public_name_and_sorting():
    lines = wm.ReferenceLines(["b", "a"], [194e12, 193e12], [1e6, 2e6], source="test")
    assert lines.labels == ("a", "b")
    np.testing.assert_array_equal(lines.center_hz, [193e12, 194e12])
    np.testing.assert_array_equal(lines.std_hz, [2e6, 1e6])
    assert len(lines) == 2
    with pytest.raises(ValueError):
        lines.center_hz[0] = 1.0  # read-only


def test_csv_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(3)
    center = np.sort(rng.uniform(191e12, 196e12, 20))
    lines = ReferenceLines(
        [f"L{k}" for k in range(20)],
        center,
        rng.uniform(1e5, 1e7, 20),
        pressure_shift_hz_per_pa=rng.normal(-7e3, 1e3, 20),
        source="a citation\nsecond line of it",
    )
    path = tmp_path / "out.csv"
    lines.to_csv(path)
    back = ReferenceLines.read_csv(path)
    assert back.labels == lines.labels
    assert back.center_hz.tobytes() == lines.center_hz.tobytes()
    assert back.std_hz.tobytes() == lines.std_hz.tobytes()
    assert back.pressure_shift_hz_per_pa.tobytes() == lines.pressure_shift_hz_per_pa.tobytes()
    assert back.source == lines.source


def test_wavelength_columns_convert_to_frequency(tmp_path):
    path = write(
        tmp_path,
        "# source line\nlabel,center_nm,std_pm,pressure_shift_pm_per_pa\nP(1),1543.114,0.1,5e-5\n",
    )
    lines = ReferenceLines.read_csv(path)
    frequency = SPEED_OF_LIGHT_M_S / 1543.114e-9
    assert lines.center_hz[0] == pytest.approx(frequency, rel=1e-15)
    # d f = f^2 d lambda / c; a longer wavelength is a lower frequency
    assert lines.std_hz[0] == pytest.approx(frequency**2 * 0.1e-12 / SPEED_OF_LIGHT_M_S)
    assert lines.pressure_shift_hz_per_pa[0] == pytest.approx(
        -(frequency**2) * 5e-17 / SPEED_OF_LIGHT_M_S
    )
    assert lines.source == "source line"


def test_frequency_unit_suffixes_and_column_order(tmp_path):
    path = write(tmp_path, "std_MHz,center_THz,label\n2,193.5,x\n1,194.0,y\n")
    lines = ReferenceLines.read_csv(path)
    np.testing.assert_allclose(lines.center_hz, [193.5e12, 194.0e12], rtol=1e-15)
    np.testing.assert_allclose(lines.std_hz, [2e6, 1e6])
    assert lines.pressure_shift_hz_per_pa is None
    np.testing.assert_array_equal(lines.centers_at(1e4), lines.center_hz)


def test_pressure_shift_and_band_selection():
    lines = ReferenceLines(
        ["a", "b", "c"], [193e12, 194e12, 195e12], [1e6] * 3, pressure_shift_hz_per_pa=[-1, -2, -3]
    )
    np.testing.assert_allclose(lines.centers_at(1000.0), [193e12 - 1e3, 194e12 - 2e3, 195e12 - 3e3])
    inside = lines.within((193.5e12, 195e12))
    assert inside.labels == ("b", "c")
    np.testing.assert_array_equal(inside.pressure_shift_hz_per_pa, [-2, -3])
    with pytest.raises(wm.InputError, match="no line of the table lies in the band"):
        lines.within((196e12, 197e12))
    with pytest.raises(wm.InputError, match="band_hz must be two finite"):
        lines.within((195e12, 194e12))
    np.testing.assert_array_equal(lines.spacing_hz(), [1e12, 1e12, 1e12])


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("label,center_hz\nx,1.93e14\n", r"lines.csv line 1: missing column\(s\) std"),
        ("label,center_hz,std_hz,colour\nx,1.93e14,1e6,red\n", "unknown column 'colour'"),
        ("label,center_hz,std_hz\nx,abc,1e6\n", r"line 2, field 'center_hz': 'abc' is not a"),
        ("label,center_hz,std_hz\nx,1.93e14,nan\n", r"line 2, field 'std_hz': 'nan' is not fin"),
        ("label,center_hz,std_hz\nx,1.93e14\n", "line 2: 2 fields, the header has 3"),
        ("label,center_hz,std_hz\nx,1.93e14,0\n", r"line 2, field 'std_hz': must be > 0"),
        ("label,center_hz,std_hz\nx,1.93e14,-1\n", r"line 2, field 'std_hz': must be > 0"),
        ("label,center_hz,std_hz\nx,1.93e9,1e6\n", r"line 2, field 'center': 1930000000.0 is not"),
        ("label,center_nm,std_nm\nx,-1550,1e-4\n", "is not an optical line centre"),
        ("label,center_hz,std_hz\nx,1.93e14,1\nx,1.94e14,1\n", r"unique, repeated: \['x'\]"),
        ("label,center_hz,std_hz\n,1.93e14,1\n", r"line 2, field 'label': empty"),
        ("label,center_hz,std_hz\n", "a header but no lines"),
        ("# only a comment\n", "no header row"),
        ("label,center_hz,center_nm,std_hz\nx,1,2,3\n", "two columns give the center"),
    ],
)
def test_bad_tables_name_the_file_line_and_field(tmp_path, text, match):
    path = write(tmp_path, text)
    with pytest.raises(wm.FileFormatError, match=match) as caught:
        ReferenceLines.read_csv(path)
    assert str(path) in str(caught.value)


def test_binary_file_is_refused(tmp_path):
    path = tmp_path / "lines.csv"
    path.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(wm.FileFormatError, match="not a UTF-8 text file"):
        ReferenceLines.read_csv(path)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"labels": [], "center_hz": [], "std_hz": []}, "at least one line"),
        ({"labels": ["a"], "center_hz": [1e9], "std_hz": [1.0]}, "optical frequencies"),
        ({"labels": ["a"], "center_hz": [1.93e14], "std_hz": [0.0]}, "std_hz must be finite"),
        ({"labels": ["a", "b"], "center_hz": [1.93e14], "std_hz": [1.0]}, "one entry per line"),
        ({"labels": ["a", "b"], "center_hz": [1.93e14] * 2, "std_hz": [1.0] * 2}, "same centre"),
    ],
)
def test_bad_values_are_refused(kwargs, match):
    with pytest.raises(wm.InputError, match=match):
        ReferenceLines(**kwargs)


def test_no_standard_table_ships():
    """No table of a standard cell is package data: none could be checked against its source
    here (docs/user-guide/absolute.rst); the simulated band says what it is in its source."""
    from importlib.resources import files

    package = files("wavemeter.reference")
    assert not [p.name for p in package.iterdir() if p.name.endswith(".csv")]
    lines, _ = wm.simulation.simulated_band_lines()
    assert lines.source.startswith("SIMULATED") and all(
        label.startswith("sim ") for label in lines.labels
    )
