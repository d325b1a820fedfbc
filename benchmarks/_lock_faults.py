"""The fault counts of benchmarks/lock.py: bad readings, the capture range, mode hops,
railing, and a corrupt reference, each injected many times into the in-process lock (or
the reference keeper) and counted."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from _lock_sim import closed_loop, reference_schedule

from wavemeter.service import ReferenceKeeper
from wavemeter.service.lock_loop import CAPTURE, HOLD_FLAGS, RAILING, LockLoop
from wavemeter.simulation import ActuatedLaser

__all__ = [
    "bad_readings",
    "capture_jumps",
    "mode_hops",
    "railing",
    "corrupt_reference",
]

KINDS = ("invalid", "off_model", "order_ambiguous")


def _loop(settings, rate_hz):
    def make():
        loop = LockLoop(settings, 0.0, interval_s=1 / rate_hz)
        loop.engage()
        return loop

    return make


def bad_readings(meter, settings, setpoint_hz, rate_hz, seconds=20.0, every=40, seed=11):
    """Every ``every``-th reading from 2 s on spoilt, the kinds in turn: how many, held,
    and how many moved the output."""
    n = int(seconds * rate_hz)
    spoil = {k: KINDS[j % 3] for j, k in enumerate(range(2000, n, every))}
    run = closed_loop(
        meter,
        lambda: ActuatedLaser(setpoint_hz, rate_hz, rng=seed, block_s=seconds + 1),
        _loop(settings, rate_hz),
        n,
        rate_hz,
        seed=seed,
        spoil=spoil,
    )
    bad = np.flatnonzero((run.flags & HOLD_FLAGS) != 0)
    moved = int(np.count_nonzero(run.output_v[bad] != run.output_v[bad - 1]))
    return {
        "injected": len(spoil),
        "flagged": len(bad),
        "held": run.loop.held,
        "moved": moved,
        "by_kind": {kind: list(spoil.values()).count(kind) for kind in KINDS},
    }


def capture_jumps(meter, settings, setpoint_hz, rate_hz, jumps=10, seed=12):
    """``jumps`` setpoint jumps of 4 GHz (capture range 3 GHz), each followed 0.5 s later
    by locking back: jumps and the unlocks they caused."""
    n = int((2 + 2 * jumps) * rate_hz)
    at = {int((2 + 2 * j) * rate_hz) for j in range(jumps)}
    back = {k + int(0.5 * rate_hz) for k in at}
    unlocked = []

    def act(k, loop, laser, reading_hz):
        if k == 0:  # a new pass
            unlocked.clear()
        if k in at:
            loop.engage(settings.with_setpoint(setpoint_hz + 4e9))
        if k - 1 in at:
            unlocked.append(not loop.engaged)
        if k in back:
            loop.engage(settings)

    run = closed_loop(
        meter,
        lambda: ActuatedLaser(setpoint_hz, rate_hz, rng=seed, block_s=n / rate_hz + 1),
        _loop(settings, rate_hz),
        n,
        rate_hz,
        seed=seed,
        act=act,
    )
    return {
        "jumps": jumps,
        "unlocked": int(sum(unlocked)),
        "alarms": run.loop.alarm_counts.get(CAPTURE, 0),
    }


def mode_hops(meter, settings, setpoint_hz, rate_hz, seconds=60.0, seed=13):
    """A laser hopping by 4 GHz (beyond the 3 GHz capture range) at 0.2 per second; after
    each unlock the lock is set again 0.2 s later on the laser's new mode: hops while locked,
    and unlocks."""
    n = int(seconds * rate_hz)
    record = {"hops": 0, "while_locked": 0, "since": 0, "engaged": True}

    def act(k, loop, laser, reading_hz):
        if k == 0:  # a new pass
            record.update(hops=0, while_locked=0, since=0, engaged=True)
        if laser.hops > record["hops"]:  # a hop in reading k - 1: was the loop engaged?
            record["while_locked"] += (laser.hops - record["hops"]) * record["engaged"]
            record["hops"] = laser.hops
        if loop.engaged:
            record["since"] = 0
        else:
            record["since"] += 1
            if record["since"] >= int(0.2 * rate_hz) and math.isfinite(reading_hz):
                loop.engage(settings.with_setpoint(reading_hz))
        record["engaged"] = loop.engaged

    run = closed_loop(
        meter,
        lambda: ActuatedLaser(
            setpoint_hz,
            rate_hz,
            rng=seed,
            mode_hop_hz=4e9,
            mode_hop_rate_per_s=0.2,
            block_s=seconds + 1,
        ),
        _loop(settings, rate_hz),
        n,
        rate_hz,
        seed=seed,
        act=act,
    )
    return {
        "hops": record["while_locked"],
        "unlocks": run.loop.alarm_counts.get(CAPTURE, 0),
    }


def railing(meter, settings, setpoint_hz, rate_hz, events=10, seed=14):
    """Output limits of +-1 V (+-500 MHz); ``events`` times the setpoint 800 MHz away for
    2 s, then back for 1 s (rail time 0.5 s): events and railing alarms."""
    limited = replace(settings, output_limits_v=(-1.0, 1.0), rail_s=0.5, setpoint=setpoint_hz)
    n = int(3 * events * rate_hz + rate_hz)
    away = {int((1 + 3 * j) * rate_hz) for j in range(events)}
    home = {k + int(2 * rate_hz) for k in away}

    def act(k, loop, laser, reading_hz):
        if k in away:
            loop.engage(limited.with_setpoint(setpoint_hz + 8e8))
        if k in home:
            loop.engage(limited)

    run = closed_loop(
        meter,
        lambda: ActuatedLaser(setpoint_hz, rate_hz, rng=seed, block_s=n / rate_hz + 1),
        _loop(limited, rate_hz),
        n,
        rate_hz,
        seed=seed,
        act=act,
    )
    return {"events": events, "alarms": run.loop.alarm_counts.get(RAILING, 0)}


def corrupt_reference(meter, reference_hz, rate_hz, sigma_hz, seconds=30.0, seed=15):
    """The keeper on a reference record with 10 readings 50 sigma off and 5 half-second
    spells of the reference 50 sigma away: attempts whose window held a corrupt reading
    (all should be refused), and the clean ones refused."""
    n = int(seconds * rate_hz)
    times = np.arange(n) / rate_hz
    truth = ActuatedLaser(reference_hz, rate_hz, noise="reference", rng=seed).take(n)
    corrupt = np.zeros(n, dtype=bool)
    for j in range(10):
        k = int((1.3 + 1.5 * j) * rate_hz)
        truth[k] += 50 * sigma_hz
        corrupt[k] = True
    for j in range(5):
        spell = (times >= 17.0 + 2.5 * j) & (times < 17.5 + 2.5 * j)
        truth[spell] += 50 * sigma_hz
        corrupt |= spell
    keeper = ReferenceKeeper(meter.calibration, reference_hz)
    _, _, events = reference_schedule(meter, keeper, truth, None, rate_hz, seed=seed)
    window = keeper.window_s
    holding = [corrupt[(times > e.time_s - window) & (times <= e.time_s)].any() for e in events]
    spoilt = [e for e, held in zip(events, holding, strict=True) if held]
    clean = [e for e, held in zip(events, holding, strict=True) if not held]
    return {
        "attempts": len(events),
        "corrupt": len(spoilt),
        "refused": sum(not e.accepted for e in spoilt),
        "clean_refused": sum(not e.accepted for e in clean),
        "clean": len(clean),
    }
