PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test test-fast tiers lint docs bench trust offmodel thermal wideband cascade scale noise absolute peers fuzz serve-bench lock-bench clean

$(BIN)/wavemeter: pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	@touch $@

demo: $(BIN)/wavemeter
	$(BIN)/wavemeter demo

test: $(BIN)/wavemeter
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

# the fast tier: every test not marked slow (under a minute on 2 cores; covers every module)
test-fast: $(BIN)/wavemeter
	$(BIN)/python -m pytest -q -m "not slow" -n 2 --dist loadfile

# the fast tier against the full suite, timed side by side, and the fast tier's coverage
tiers: $(BIN)/wavemeter
	$(BIN)/python benchmarks/test_tiers.py

lint: $(BIN)/wavemeter
	$(BIN)/ruff check src tests benchmarks examples
	$(BIN)/ruff format --check src tests benchmarks examples
	$(BIN)/lint-imports

# the documentation site: docs/_build/html, offline, warnings as errors. Built from scratch
# every time (the gallery's examples run again, the API pages are written again), so no
# warning hides in a page cached from an earlier build; about 2 minutes on 2 cores.
DOCS_GENERATED := docs/_build docs/gallery docs/reference/generated docs/reference/_api \
	docs/sg_execution_times.rst
docs: $(BIN)/wavemeter
	rm -rf $(DOCS_GENERATED)
	$(BIN)/sphinx-build -b html -W --keep-going docs docs/_build/html

# 10,000 hypothesis examples per file reader (a tenth through `wavemeter measure`) and for the
# calibration loader, new ones each run (the "fuzz" profile; `make test` draws the same ones
# every run); the seed is printed: repeat a run with `make fuzz FUZZ_SEED=<seed>`, change the
# count with FUZZ_EXAMPLES
FUZZ_EXAMPLES ?= 10000
fuzz: $(BIN)/wavemeter
	@seed=$${FUZZ_SEED:-$$(od -An -N4 -tu4 /dev/urandom | tr -d ' ')}; \
	echo "fuzz: $(FUZZ_EXAMPLES) examples per reader, seed $$seed (make fuzz FUZZ_SEED=$$seed)"; \
	WAVEMETER_FUZZ_EXAMPLES=$(FUZZ_EXAMPLES) $(BIN)/python -m pytest -q -p no:cacheprovider \
		tests/test_fuzz_readers.py tests/test_fuzz_calibration_files.py \
		--hypothesis-profile=fuzz --hypothesis-seed=$$seed

bench: $(BIN)/wavemeter
	$(BIN)/python benchmarks/precision.py

# the fault catalogue of issue 9: every fault at three severities, warnings, flags, remedies
trust: $(BIN)/wavemeter
	$(BIN)/python benchmarks/trust.py

# issue 29: OFF_MODEL against the calibration's own distances, old and new rule side by side on
# simulated devices (clean, with a model error) and the measured fibre coupler (about a minute)
offmodel: $(BIN)/wavemeter
	$(BIN)/python benchmarks/offmodel.py

# the thermally compensated calibration of issue 10: ThermalCalibrator against its bound, plain
# and re-anchored plain calibrations; writes docs/figures/thermal_error_vs_temperature.png
thermal: $(BIN)/wavemeter
	$(BIN)/python benchmarks/thermal.py

# the wide-band calibration of issue 11 over the C band; writes docs/figures/wideband_residual_phase.png
wideband: $(BIN)/wavemeter
	$(BIN)/python benchmarks/wideband.py

# the cascade of issue 12 over the C band: wrong orders seen vs predicted, no coarse input
cascade: $(BIN)/wavemeter
	$(BIN)/python benchmarks/cascade.py

# issue 13: fit, predict, measure, calibrate, stream and fleet at scale, side by side (about 6 min)
scale: $(BIN)/wavemeter
	$(BIN)/python benchmarks/scale.py

# issue 14: linewidth, PSD and Allan deviations of simulated lasers read through a simulated
# meter, vs the truth and vs allantools/scipy by hand; writes docs/figures/noise_psd.png and
# docs/figures/noise_adev.png
noise: $(BIN)/wavemeter
	$(BIN)/python benchmarks/noise.py

# issue 30: wavemeter serve vs stream, latency at 1 kHz with 1 and 3 subscribers (one stopped),
# CPU per 1 kHz channel, the highest sustained rate with logging (a few minutes)
serve-bench: $(BIN)/wavemeter
	$(BIN)/python benchmarks/serve.py

# issue 31: locks on the simulated laser and meter, free-running / locked / 1 GHz away / a 2 K
# chip ramp without and with a reference, against the PI bound; fault counts; a run through
# serve (three seeds of 60 s at 1 kHz, a few minutes)
lock-bench: $(BIN)/wavemeter
	$(BIN)/python benchmarks/lock.py

# issue 32: absolute accuracy from a reference cell: plain, axis-corrected and self-calibrated
# over a simulated cell's band, three laser presets, 3/4/5 ports, three seeds (15-35 min)
absolute: $(BIN)/wavemeter
	cd benchmarks && ../$(BIN)/python absolute.py

peers: $(BIN)/wavemeter
	$(BIN)/python -m pip install --quiet -e '.[dev,peers]'
	$(BIN)/python -m pip install --quiet --no-deps 'hoqi-bench>=0.1.1' 'minipti>=1.9.3'
	$(BIN)/python benchmarks/peers.py

clean:
	rm -rf $(VENV) wavemeter-demo $(DOCS_GENERATED)
