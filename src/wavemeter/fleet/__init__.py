"""Fleets of devices: calibrate every device of a wafer from its sweep file, in parallel.

:func:`calibrate_fleet` runs one calibration per device on dask.distributed (a
``LocalCluster`` by default, any running scheduler by address, or in this process) and
writes each device's calibration, a summary table (CSV and Parquet) and an HTML page with
histograms and a wafer map. Modules: ``run`` (the run, the only module that imports dask),
``summary`` (the table), ``page`` (``fleet.html``).
"""

from .run import FleetResult, calibrate_fleet
from .summary import SUMMARY_COLUMNS, die_position

__all__ = ["calibrate_fleet", "FleetResult", "SUMMARY_COLUMNS", "die_position"]
