"""Lock outputs of other packages: ``tests/plugins/wavemeter_toy_output`` installed beside
the package (its module and the ``.dist-info`` with its entry points, as an installer
writes them), found by ``wavemeter serve --output 0=toy_file:...`` through the
``wavemeter.outputs`` entry points, driven by a lock, closed at the end; an unknown one is
an error line naming those installed."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from ._service import (
    EPHEMERAL,
    addresses_of,
    feed_lines,
    make_meter,
    serving,
    source_port,
    wait_for,
)

pytest.importorskip("zmq", reason="the serve extra (pyzmq) is not installed")

from wavemeter.service import Client  # noqa: E402
from wavemeter.service.simulated import NOISE_W, POWER_W  # noqa: E402

pytestmark = pytest.mark.slow

PACKAGE = Path(__file__).parent / "plugins" / "wavemeter_toy_output"


def install(package: Path, target: Path) -> Path:
    """Put ``package`` on a path of its own as an installer would for entry points: its
    module and ``<name>-<version>.dist-info`` with ``METADATA`` and ``entry_points.txt``
    (read by ``importlib.metadata`` on ``sys.path``). No build, no network."""
    settings = tomllib.loads((package / "pyproject.toml").read_text())
    project = settings["project"]
    for module in settings["tool"]["setuptools"]["py-modules"]:
        shutil.copy(package / f"{module}.py", target / f"{module}.py")
    name = project["name"].replace("-", "_")
    info = target / f"{name}-{project['version']}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {project['name']}\nVersion: {project['version']}\n"
    )
    groups = [
        f"[{group}]\n" + "".join(f"{key} = {value}\n" for key, value in points.items())
        for group, points in project["entry-points"].items()
    ]
    (info / "entry_points.txt").write_text("\n".join(groups))
    return target


def lines_at(device, frequency_hz: float, count: int, rng) -> list[str]:
    """Lines of port powers (mW) of a laser at ``frequency_hz``."""
    powers = device.powers(np.full(count, frequency_hz), power_w=POWER_W, noise_w=NOISE_W, rng=rng)
    return [",".join(repr(float(p)) for p in row * 1e3) for row in powers]


@pytest.fixture(scope="module")
def meter(tmp_path_factory):
    return make_meter(tmp_path_factory)


@pytest.fixture(scope="module")
def plugins(tmp_path_factory):
    return install(PACKAGE, tmp_path_factory.mktemp("site"))


def test_a_plugin_output_is_found_driven_by_a_lock_and_closed(meter, plugins, tmp_path):
    device, folder = meter
    written = tmp_path / "dac.txt"
    args = [
        str(folder / "chip.wmcal.json"),
        "--source",
        "tcp://127.0.0.1:0",
        "--output",
        f"0=toy_file:path={written},low=-2,high=2,start=0.5",
        *EPHEMERAL,
    ]
    rng = np.random.default_rng(1)
    with serving(args, env={"PYTHONPATH": str(plugins)}) as service:
        with Client(**addresses_of(service)) as client:
            status = client.lock_status(0)
            assert status["sink"] == "output plug-in toy_file"
            assert status["output_v"] == 0.5 and status["output_limits_v"] == [-2.0, 2.0]
            setpoint = device.center_hz + 1e8  # the laser stays 100 MHz below (no plant)
            client.lock(0, setpoint, actuator_hz_per_v=5e8, bandwidth_hz=2.0)
            with feed_lines(source_port(service), lines_at(device, device.center_hz, 200, rng)):
                assert wait_for(lambda: client.lock_status(0)["updates"] >= 200, 10)
            status = client.lock_status(0)
    lines = written.read_text().splitlines()
    assert lines[-1] == "closed"
    volts = [float(line.split()[1]) for line in lines[:-1]]
    assert len(volts) >= 2 and all(line.startswith("0 ") for line in lines[:-1])
    assert volts[-1] == pytest.approx(status["output_v"])
    assert all(-2.0 <= v <= 2.0 for v in volts)


def test_an_unknown_output_plugin_is_an_error_line_naming_those_installed(meter, plugins):
    _, folder = meter
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "wavemeter",
            "serve",
            str(folder / "chip.wmcal.json"),
            "--output",
            "0=nope",
            *EPHEMERAL,
        ],
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "PYTHONPATH": str(plugins)},
    )
    assert result.returncode == 2
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("error: no output plug-in 'nope'") and "toy_file" in last
