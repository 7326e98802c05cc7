# make demo   run the demo network on simulated sensors (DEMO_SECONDS=N stops after N s;
#             RGBD=1 renders depth images and runs the real detector on them)
# make test   run the test suite (test files spread over every core)
# make bench  print benchmark figures as JSON
# Each target creates and fills .venv first when needed.

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.bootstrapped
EXTRAS ?= dev,osc,web,security,sensor
DEMO_SECONDS ?=
RGBD ?=
DEMO_ARGS ?= $(if $(RGBD),--set sim.sensor_model=rgbd --set detector.rate_hz=15)

.PHONY: demo test bench lint format venv clean

$(STAMP): pyproject.toml scripts/bootstrap
	PYTHON=$(PYTHON) ./scripts/bootstrap $(EXTRAS)
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/openptrack launch demo --table $(if $(DEMO_SECONDS),--duration $(DEMO_SECONDS)) $(DEMO_ARGS)

test: $(STAMP)
	$(PY) -m pytest -n auto --dist loadfile

bench: $(STAMP)
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 $(PY) -m benchmarks.run_all

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

format: $(STAMP)
	$(VENV)/bin/ruff format .
	$(VENV)/bin/ruff check --fix .

clean:
	rm -rf $(VENV) build dist *.egg-info .pytest_cache .ruff_cache .hypothesis
