"""The two test tiers side by side: the fast tier (``pytest -m "not slow"``) against the full
suite, timed one after the other in one run, and what the fast tier covers.

Targets (issue 27, item 7): the fast tier takes under a quarter of the full suite's time and
under a minute on 2 cores, and covers every module of ``src/wavemeter`` (no module without
a line run by it). Each tier is timed once (they take minutes): wall time, and the CPU time
of the pytest process and what it started, with the load average before and after (the
machine is shared: a loaded machine stretches wall times, not CPU times). Coverage is
measured in separate runs under ``coverage run`` with ``source = wavemeter`` and ``patch =
subprocess`` (the Python processes tests start are measured too; numba-compiled code is
not traced).

Usage: ``python benchmarks/test_tiers.py [--no-full-coverage]`` (``make tiers``)
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from _script import Parser

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "wavemeter"
PYTEST = ["-m", "pytest", "-q", "-p", "no:cacheprovider"]
FAST = ["-m", "not slow"]
#: the timed runs spread whole files over both cores, as ``make test`` and ``make test-fast``
CORES = ["-n", "2", "--dist", "loadfile"]
#: the targets: the fast tier's share of the full suite's time, and its wall time (s)
MAX_RATIO = 0.25
MAX_FAST_S = 60.0


@dataclass(frozen=True)
class Run:
    """One pytest run: its exit code, last line, wall and CPU time (s)."""

    code: int
    summary: str
    wall_s: float
    cpu_s: float


def load_average() -> str:
    return " ".join(f"{value:.2f}" for value in os.getloadavg())


def run(arguments: list[str]) -> Run:
    """Run ``python ARGUMENTS`` in the repository: its exit code, pytest's last line, wall
    time and the CPU time (user + system) of it and its children."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, *arguments], cwd=ROOT, capture_output=True, text=True, check=False
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    lines = done.stdout.strip().splitlines() or done.stderr.strip().splitlines() or [""]
    return Run(done.returncode, lines[-1].strip("= "), wall, cpu)


def covered_lines(data_file: Path) -> dict[Path, tuple[int, int]]:
    """(statements, statements run) of every module of ``src/wavemeter``, from the coverage
    data files of a run and its subprocesses; a module never imported has none run."""
    import coverage

    measured = coverage.Coverage(data_file=str(data_file))
    measured.combine([str(data_file.parent)], keep=True)
    counts = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        _, statements, _, missing, _ = measured.analysis2(str(path))
        counts[path.relative_to(PACKAGE.parent)] = (len(statements), len(statements) - len(missing))
    return counts


def coverage_run(folder: Path, arguments: list[str]) -> Run:
    """A pytest run under coverage, the Python subprocesses it starts measured too (data
    files in ``folder``)."""
    folder.mkdir()
    settings = folder / "coveragerc"
    settings.write_text(
        "[run]\nsource = wavemeter\nparallel = true\npatch = subprocess\n"
        f"data_file = {folder / 'data'}\n"
    )
    return run(["-m", "coverage", "run", f"--rcfile={settings}", *PYTEST, *arguments])


def main(argv: list[str] | None = None) -> int:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--no-full-coverage",
        action="store_true",
        help="skip the full suite's coverage run (the fast tier's coverage alone)",
    )
    args = parser.parse_args(argv)
    print(f"{os.cpu_count()} cores; load average at start {load_average()} (1, 5, 15 min)")
    fast = run([*PYTEST, *CORES, *FAST])
    full = run([*PYTEST, *CORES])
    with tempfile.TemporaryDirectory() as folder:
        fast_data, full_data = Path(folder) / "fast", Path(folder) / "full"
        fast_coverage = coverage_run(fast_data, FAST)
        fast_counts = covered_lines(fast_data / "data")
        full_counts = None
        if not args.no_full_coverage:
            full_coverage = coverage_run(full_data, [])
            full_counts = covered_lines(full_data / "data")
    print(f"load average at end {load_average()}\n")

    print("| tier | wall (s) | CPU (s) | pytest |")
    print("| --- | ---: | ---: | --- |")
    for name, result in (("fast (-m 'not slow')", fast), ("full", full)):
        print(f"| {name} | {result.wall_s:.1f} | {result.cpu_s:.1f} | {result.summary} |")
    wall_ratio, cpu_ratio = fast.wall_s / full.wall_s, fast.cpu_s / full.cpu_s
    print(f"\nfast / full: {wall_ratio:.3f} of the wall time, {cpu_ratio:.3f} of the CPU time\n")

    print("| coverage of src/wavemeter | lines | run | % | pytest |")
    print("| --- | ---: | ---: | ---: | --- |")
    rows = [("fast tier", fast_counts, fast_coverage)]
    if full_counts is not None:
        rows.append(("full suite", full_counts, full_coverage))
    for name, counts, result in rows:
        statements = sum(count for count, _ in counts.values())
        ran = sum(done for _, done in counts.values())
        print(
            f"| {name} | {statements} | {ran} | {100 * ran / statements:.1f} | {result.summary} |"
        )
    uncovered = [str(path) for path, (count, done) in fast_counts.items() if count and not done]
    print(f"\nmodules with no line run by the fast tier: {', '.join(uncovered) or 'none'}")
    if full_counts is not None:
        print("\nlargest drops from the full suite's coverage to the fast tier's (lines run):")
        print("| module | full | fast |")
        print("| --- | ---: | ---: |")
        drops = sorted(fast_counts, key=lambda path: fast_counts[path][1] - full_counts[path][1])
        for path in drops[:10]:
            print(f"| {path} | {full_counts[path][1]} | {fast_counts[path][1]} |")

    verdicts = [
        (fast.code == 0 and full.code == 0, "both tiers pass"),
        (wall_ratio < MAX_RATIO, f"fast tier under {MAX_RATIO:g} of the full suite's wall time"),
        (fast.wall_s < MAX_FAST_S, f"fast tier under {MAX_FAST_S:g} s wall time"),
        (not uncovered, "every module has lines run by the fast tier"),
    ]
    print()
    for passed, target in verdicts:
        print(f"{'PASS' if passed else 'FAIL'} {target}")
    return 0 if all(passed for passed, _ in verdicts) else 1


if __name__ == "__main__":
    sys.exit(main())
