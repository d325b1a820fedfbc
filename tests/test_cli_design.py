"""`wavemeter design`: the table, the JSON, and bad input as one ``error:`` line."""

from __future__ import annotations

import json

import pytest

import wavemeter as wm

from .helpers import one_error
from .helpers import run_cli as run

EXAMPLE = "design --band 191THz:195.4THz --finest-fsr 50GHz --noise 0.5uW"


def test_the_example_prints_one_row_per_stage_and_the_total(capsys):
    code, out, err = run(capsys, EXAMPLE)
    assert code == 0 and err == ""
    design = wm.design_cascade((191e12, 195.4e12), 50e9, noise_w=5e-7)
    lines = out.splitlines()
    assert lines[0].split() == "stage FSR GHz ratio std MHz margin (std) hand-over rate".split()
    rows = [line.split() for line in lines[1 : 1 + design.stages]]
    assert [row[0] for row in rows] == [str(k + 1) for k in range(design.stages)]
    for row, fsr in zip(rows, design.fsrs_hz, strict=True):
        assert float(row[1]) == pytest.approx(fsr / 1e9, rel=1e-5)
    for row, margin in zip(rows, design.handover_margins, strict=False):
        assert float(row[4]) == pytest.approx(margin, abs=0.006)
    assert rows[-1][2] == rows[-1][4] == "-"  # the finest stage hands over to none
    assert f"{design.wrong_order_rate:.3g} predicted (1e-09 requested)" in lines[-1]


def test_json_is_the_python_design(capsys):
    code, out, _ = run(capsys, EXAMPLE + " --json --ports 4 --power 2mW --rate 1e-12")
    assert code == 0
    printed = json.loads(out)
    design = wm.design_cascade(
        (191e12, 195.4e12), 50e9, ports=4, power_w=2e-3, noise_w=5e-7, wrong_order_rate=1e-12
    )
    assert printed == json.loads(json.dumps(design.to_dict()))
    assert printed["fsrs_hz"][-1] == 50e9 and printed["requested_rate"] == 1e-12


def test_a_wavelength_band_is_the_same_band(capsys):
    from wavemeter.units import SPEED_OF_LIGHT_M_S

    printed = json.loads(run(capsys, "design --band 1530nm:1565nm --finest-fsr 50GHz --json")[1])
    low, high = SPEED_OF_LIGHT_M_S / 1565e-9, SPEED_OF_LIGHT_M_S / 1530e-9
    assert printed["band_hz"] == pytest.approx([low, high], rel=1e-12)


def test_forced_stages_that_miss_the_rate_are_shown_with_a_warning(capsys):
    code, out, err = run(capsys, EXAMPLE.replace("0.5uW", "5uW") + " --stages 2")
    assert code == 0 and len(out.splitlines()) == 1 + 2 + 3  # header, 2 stages, 3 lines
    assert err.startswith("warning: [rate_not_met] 2 stage(s)") and err.count("\n") == 1


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ("--band 191THz:191THz --finest-fsr 50GHz", "the band's ends must differ"),
        ("--band 191:195.4 --finest-fsr 50GHz", "did you mean 191THz?"),
        ("--band 191THz --finest-fsr 50GHz", "is not a band"),
        ("--band 191THz:195.4THz --finest-fsr 50", "did you mean 50GHz?"),
        ("--band 191THz:195.4THz --finest-fsr 50GHz --noise 0", "must be > 0"),
        ("--band 191THz:195.4THz --finest-fsr 50GHz --rate 1", "--rate"),
        ("--finest-fsr 50GHz", "Missing option '--band'"),
        (
            "--band 191THz:195.4THz --finest-fsr 50GHz --noise 50uW --rate 1e-12",
            "noise_w: --noise",
        ),
        ("--band 191THz:195.4THz --finest-fsr 50GHz --stages 1", "(use --stages)"),
    ],
)
def test_bad_input_is_one_error_line(capsys, options, expected):
    code, out, err = run(capsys, f"design {options}")
    assert expected in one_error(code, err) and out == ""


def test_a_band_reads_the_same_whichever_end_comes_first(capsys):
    """Frequencies and wavelengths alike: the band is from its lower to its higher
    frequency (the shared ``LOW:HIGH`` option of simulate and design)."""
    outputs = []
    for band in ("191THz:195.4THz", "195.4THz:191THz"):
        code, out, _ = run(capsys, f"design --band {band} --finest-fsr 50GHz --json")
        assert code == 0
        outputs.append(json.loads(out))
    assert outputs[0] == outputs[1]
