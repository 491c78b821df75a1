# make demo   set up .venv and analyze the bundled sample_data/
# make test   set up .venv and run the test suite
# make bench  set up .venv (with benchmark extras) and write bench-results/
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
CLOTHTOOL := $(VENV)/bin/clothtool

.PHONY: demo test bench clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[test,bench]'
	touch $@

demo: $(VENV)/.installed
	mkdir -p demo-out
	$(CLOTHTOOL) analyze sample_data/sheet -o demo-out/sheet.h5
	$(CLOTHTOOL) analyze sample_data/sheet -o demo-out/sheet_uv.h5 --reference uv

test: $(VENV)/.installed
	$(PY) -m pytest -q

bench: $(VENV)/.installed
	$(PY) -m benchmarks

clean:
	rm -rf demo-out bench-results .pytest_cache .hypothesis
