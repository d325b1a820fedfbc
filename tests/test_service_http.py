"""The HTTP side of `wavemeter serve`: /metrics parses as Prometheus text, and the
dashboard, in a real headless Chromium, shows live values that change and logs no error."""

from __future__ import annotations

import shutil
import time
import urllib.request

import pytest
from prometheus_client.parser import text_string_to_metric_families  # noqa: E402

from ._service import EPHEMERAL, serving, wait_for

CHROMIUM = shutil.which("chromium")

#: each test starts real `wavemeter serve` processes (seconds each): not the fast tier
pytestmark = pytest.mark.slow


def _metrics(url: str) -> dict:
    with urllib.request.urlopen(url + "metrics", timeout=10) as answer:
        assert answer.headers["Content-Type"].startswith("text/plain")
        text = answer.read().decode()
    return {family.name: family for family in text_string_to_metric_families(text)}


def _value(family, **labels) -> float | None:
    """The family's sample with these labels (a counter's ``_total``), None if none."""
    name = family.name + ("_total" if family.type == "counter" else "")
    for sample in family.samples:
        if sample.name == name and all(sample.labels.get(k) == v for k, v in labels.items()):
            return sample.value
    return None


def test_metrics_parse_as_prometheus_text():
    with serving(["--simulate", "--channels", "2", *EPHEMERAL]) as service:
        url = service.addresses["http"]
        assert wait_for(
            lambda: (_value(_metrics(url)["wavemeter_readings"], channel="1") or 0) > 100
        )
        first = _metrics(url)
        time.sleep(1.5)
        second = _metrics(url)
    for name in (
        "wavemeter_readings",
        "wavemeter_readings_per_second",
        "wavemeter_latency_seconds",
        "wavemeter_subscribers",
        "wavemeter_dropped_readings",
        "wavemeter_channel_signal",
        "wavemeter_frequency_hz",
    ):
        assert name in second, name
    for channel in ("0", "1"):
        grown = _value(second["wavemeter_readings"], channel=channel) - _value(
            first["wavemeter_readings"], channel=channel
        )
        # 1.5 s at 500 readings/s per channel (the scrapes' own timing on a busy machine aside)
        assert 300 < grown < 1200
        rate = _value(second["wavemeter_readings_per_second"], channel=channel)
        assert 250 < rate < 750
        assert _value(second["wavemeter_channel_signal"], channel=channel) == 1
        count = [
            s.value
            for s in second["wavemeter_latency_seconds"].samples
            if s.name.endswith("_count") and s.labels["channel"] == channel
        ]
        assert count and count[0] > 0
    assert 1.9e14 < _value(second["wavemeter_frequency_hz"], channel="0") < 2e14


@pytest.mark.skipif(CHROMIUM is None, reason="LOUD SKIP: chromium is not installed")
def test_the_dashboard_shows_live_values_in_chromium():
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed")
    with serving(["--simulate", "--channels", "2", *EPHEMERAL]) as service:
        url = service.addresses["http"]
        with sync_api.sync_playwright() as playwright:
            browser = playwright.chromium.launch(
                executable_path=CHROMIUM, args=["--no-sandbox", "--disable-gpu"]
            )
            try:
                page = browser.new_page()
                problems = []
                page.on(
                    "console",
                    lambda m: (
                        problems.append(f"{m.type}: {m.text}")
                        if m.type in ("error", "warning")
                        else None
                    ),
                )
                page.on("pageerror", lambda error: problems.append(str(error)))
                page.goto(url)
                page.wait_for_function(
                    "document.querySelectorAll('.channel .frequency').length == 2 && "
                    "document.querySelector('.channel .frequency').textContent.endsWith('THz')",
                    timeout=20000,
                )
                seen = set()
                for _ in range(8):
                    seen.add(page.inner_text(".channel .frequency"))
                    time.sleep(0.4)
                details = page.inner_text(".channel .details")
                status = page.inner_text(".channel .status")
                connection = page.inner_text("#connection")
                plotted = page.evaluate("document.querySelectorAll('.channel canvas').length")
            finally:
                browser.close()
    assert len(seen) >= 3, seen  # live values that change
    assert all(value.endswith(" THz") and float(value.split()[0]) > 190 for value in seen)
    assert "readings/s" in details and status == "ok" and connection == "live"
    assert plotted == 4  # a trace and an Allan deviation per channel
    assert problems == []
