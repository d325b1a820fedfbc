"""The locks page's worked DAC example runs as written: the sink the page shows, on a bus that
records what it is sent, sends the codes a 16-bit +-10 V DAC takes, refuses a voltage outside
its limits (as the service expects a failure to be reported), and passes the service's check
of a sink; the page's entry-point table names the group the service reads."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

from wavemeter.exceptions import InputError
from wavemeter.service.outputs import ENTRY_POINT_GROUP, check_sink

PAGE = Path(__file__).parent.parent / "docs" / "user-guide" / "locks.rst"


def _blocks(language: str) -> list[str]:
    text = PAGE.read_text(encoding="utf-8")
    found = re.findall(rf"\.\. code-block:: {language}\n\n((?:   .*\n|\n)+)", text)
    return ["\n".join(line[3:] for line in block.splitlines()) for block in found]


class RecordingBus:
    def __init__(self):
        self.sent: list[bytes] = []
        self.closed = False

    def write(self, data: bytes) -> None:
        self.sent.append(data)

    def close(self) -> None:
        self.closed = True


@pytest.fixture
def dac_module():
    code = next(block for block in _blocks("python") if "class SerialDac" in block)
    namespace: dict = {}
    exec(compile(code, str(PAGE), "exec"), namespace)  # noqa: S102 - the page's own code
    return namespace


def test_the_pages_dac_sends_the_codes_of_a_16_bit_bipolar_dac(dac_module):
    bus = RecordingBus()
    dac = dac_module["SerialDac"](bus, 2, low=-5.0, high=5.0, start=0.25)
    assert check_sink(dac, "the page's DAC") is dac
    assert dac.output_v == 0.25 and dac.limits_v == (-5.0, 5.0)
    for voltage in (-5.0, 0.0, 5.0, 1.2345):
        dac.write(voltage)
    # code = round((v + 10) / 20 x 65535): -5 V a quarter, 0 V the middle, 5 V three quarters
    codes = [int.from_bytes(message[1:], "big") for message in bus.sent]
    assert [message[0] for message in bus.sent] == [2] * 4
    assert codes == [16384, 32768, 49151, round((1.2345 + 10) / 20 * 65535)]
    assert dac.output_v == 1.2345
    with pytest.raises(ValueError, match="outside"):
        dac.write(5.5)
    assert len(bus.sent) == 4 and dac.output_v == 1.2345  # nothing sent, output unchanged
    dac.close()
    assert bus.closed


def test_a_dac_with_limits_the_wrong_way_round_is_refused_by_the_service(dac_module):
    dac = dac_module["SerialDac"](RecordingBus(), 0, low=5.0, high=-5.0)
    with pytest.raises(InputError, match="low < high"):
        check_sink(dac, "the page's DAC")


def test_the_pages_entry_point_is_in_the_group_the_service_reads():
    (table,) = _blocks("toml")
    points = tomllib.loads(table)["project"]["entry-points"]
    assert list(points) == [ENTRY_POINT_GROUP]
    assert points[ENTRY_POINT_GROUP] == {"serial_dac": "my_dac:serial_dac"}
