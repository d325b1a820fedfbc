"""Smoke test of the peers benchmark's core functions on 2 devices per regime."""

from __future__ import annotations

import importlib
import warnings

import numpy as np
import pytest

from .helpers import BENCHMARKS, table_rows

pytestmark = pytest.mark.slow

DEVICES = 2


@pytest.fixture(scope="module")
def peers():
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        yield importlib.import_module("peers")


@pytest.fixture(scope="module")
def all_results(peers):
    methods = peers.library_methods()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", peers.NonlinearFitWarning)
        return {
            regime.key: {
                ports: peers.run_regime(
                    regime,
                    ports,
                    methods,
                    devices=DEVICES,
                    seed=1,
                    convergence_devices=1,
                    starts=3,
                    test_samples=500,
                )
                for ports in peers.PORTS
            }
            for regime in peers.REGIMES
        }


def test_regime_tables_have_a_row_per_method_and_port_count(peers, all_results):
    methods = [method.name for method in peers.library_methods()]
    for by_ports in all_results.values():
        rows = table_rows(peers.regime_table(by_ports))
        assert rows[0][:3] == ["method", "ports", "RMS (MHz)"]
        assert all(len(row) == len(rows[0]) for row in rows)
        body = rows[2:]
        assert [row[0] for row in body] == methods * len(peers.PORTS)
        assert all(row[-1].endswith(f"/{DEVICES}") for row in body)


def test_learned_is_near_the_bound_on_table1(peers, all_results):
    for results in all_results["table1"].values():
        learned = results[peers.LEARNED]
        assert learned.failed == 0
        ratios = np.array(learned.over_crlb)
        assert ratios.shape == (DEVICES,)
        assert np.all(np.isfinite(ratios)) and np.all(ratios < 1.5)
        assert len(results[peers.NONLINEAR].convergence) == 1


def test_summary_and_targets_tables(peers, all_results):
    summary = table_rows(peers.summary_table(all_results, 3))
    assert summary[0][1:] == [regime.key for regime in peers.REGIMES]
    targets = table_rows(peers.targets_table(all_results, None))
    assert targets[0] == ["target", "measured", "status"]
    assert {row[2] for row in targets[2:]} <= {"met", "missed", "n/a"}
    assert len(targets) - 2 == 2 * len(peers.REGIMES) + 4  # two learned variants


def test_quadrature_pair(peers):
    assert peers.quadrature_pair(np.radians([120, 0, -120])) == (0, 1)
    assert peers.quadrature_pair(np.radians([135, 45, -135, -45])) == (0, 1)
    assert peers.quadrature_pair(np.radians([0, 180, 90])) == (0, 2)


def test_phase_difference_ignores_offset_and_sign(peers):
    reference = np.linspace(0, 9, 200)
    assert peers.phase_difference_rms_rad(-reference + 2.0, reference) < 1e-12


def test_hoqi_peer_on_a_sweep(peers, all_results):
    methods = peers.hoqi_methods()
    if not methods:
        pytest.skip("hoqi-bench not installed")
    heydemann = [m for m in methods if m.name.endswith("heydemann")]
    results = peers.run_regime(peers.REGIMES[0], 3, heydemann, devices=1, seed=1, test_samples=500)
    result = results[heydemann[0].name]
    assert result.failed == 0 and result.median_over_crlb() < 3


def test_measured_data_with_peers(peers):
    if not (peers.DATA_DIR / "Decimation_Comercial.csv").exists():
        pytest.skip("measured MiniPTI data not found")
    readings, published = peers.load_measured(peers.DATA_DIR)
    assert readings.shape == (published.size, 3)
    external = importlib.import_module("external_peers")
    try:
        solver = external.minipti_solver(peers.DATA_DIR / "settings.csv")
    except external.PeerUnavailable:
        pytest.skip("minipti not installed")
    rms = peers.phase_difference_rms_rad(solver(readings[:50]), published[:50])
    assert rms < 0.05


def test_port_faults_benchmark_warns_and_its_remedy_restores_the_bound():
    """Each broken port is named by the fit's warning; dropping it brings back the bound."""
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        port_faults = importlib.import_module("port_faults")
    for fault in ("dead", "stuck", "saturated"):
        result = port_faults.one_device(fault, seed=3)
        assert result["warned"] and result["cause"] == "dead_port"
        # three good ports of a Table 1 hybrid: the pseudo-inverse's excess stays small
        assert result["with"] < 1.2
    assert port_faults.one_device("stuck", seed=3)["without"] > 5


def test_trust_causes_table_names_a_rounded_axis_and_leaves_a_stepped_laser_alone(capsys):
    """The catalogue's causes table (issue 29) on its two cheapest rows, one seed each,
    through ``trust.main``: the rounded axis is named, the control warns nothing, and the
    verdict has its two lines."""
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        trust = importlib.import_module("trust")
        trust.main(["--quick", "--faults", "partial_span", "--cause-rows", "rounded_pm,stepped"])
    text = capsys.readouterr().out
    causes = text[text.index("## Causes") :]
    table = table_rows("\n".join(line for line in causes.splitlines() if line.startswith("| ")))
    headers, rounded, stepped = table
    assert headers == list(importlib.import_module("trust_causes").HEADERS)
    assert rounded[2:5] == ["1/1: quantised_axis 1", "quantised_axis", "1/1"]
    assert stepped[2:4] == ["0/1", "none"] and stepped[5].startswith("0/1")
    verdict = [line for line in causes.splitlines() if line.startswith(("PASS ", "FAIL "))]
    assert [line.split()[0] for line in verdict] == ["PASS", "PASS"]


def test_trust_catalogue_quick_prints_its_rows_and_the_verdict(capsys):
    """The fault catalogue in its tiny configuration, on one fault (the fits take the time):
    a row per severity and per clean port count, and a line per target."""
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        trust = importlib.import_module("trust")
        trust.main(["--quick", "--seed", "1", "--faults", "thermal_ramp"])
    lines = capsys.readouterr().out.splitlines()
    table = table_rows("\n".join(line for line in lines if line.startswith("| ")))
    assert table[0] == list(trust.HEADERS)
    body = {(row[0], row[1]): row for row in table[1:]}
    assert len(table) - 1 == len(body) == 3 + 3
    verdict = [line for line in lines if line.startswith(("PASS ", "FAIL "))]
    assert len(verdict) == 5
    ratio = table[0].index("RMS/CRLB")
    # clean: the learned calibration reaches CRLB sqrt(1 + 3/201) on 300 test readings, whose
    # RMS has a relative standard error of 1/sqrt(600) = 4 %: 5 standard errors either side
    for ports in (3, 4, 5):
        assert 0.8 < float(body[(f"clean, {ports} ports", "-")][ratio]) < 1.25
    # a 1 rad ramp over a one-way sweep: a phase error of 1 rad (f - f0) / FSR, RMS
    # 1/sqrt(12) rad = 2.3 GHz at 50 GHz, against a bound of about 15 MHz
    assert float(body[("thermal ramp, one-way sweep", "1 K")][ratio]) > 50
