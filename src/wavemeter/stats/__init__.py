"""Generic statistics of long series of readings on several channels.

Passes over tall arrays in blocks of rows and their Householder QR (:mod:`.blocks`), the
discrete cosine transform by block Taylor series (:mod:`.cosine_transform`), projections off
fitted directions and test columns factored beside a residual (:mod:`.projection`,
:mod:`.cosine_columns`), nested F tests of a whitened residual (:mod:`.nested_tests`) and a
noise estimate that needs no model (:mod:`.model_free_noise`). These modules import numpy,
scipy and nothing else of wavemeter; the fit diagnostics
(:mod:`wavemeter.calibration.checks.misfit`) build on them.
"""
