# make demo   set up .venv, analyze the bundled sample_data/, simulate and analyze a hanging sheet
#             and a sheet draped over a body (contact, no intersections), then dress a walking
#             mannequin in a two-panel skirt (sewn, attached) and render it: a picture and a movie
# make test   set up .venv and run the test suite
# make bench  set up .venv (with benchmark extras) and write bench-results/ (the long cases and
#             the peers too: .venv/bin/python -m benchmarks --full; README.md: Benchmarks)
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
CLOTHTOOL := $(VENV)/bin/clothtool

.PHONY: demo test bench clean

# One stamp per set of extras, each what its target needs: plot (matplotlib) for the demo,
# bench for the benchmarks, test (which holds bench's) for the suite; a venv that has one set
# gets the others added when a target asks for them.
$(VENV)/.installed-%: pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[$*]'
	touch $@

# The demo's four parts two at a time: in a fresh clone most of each is numba compiling its
# kernels (one core each); the garment after the drape, whose contact kernels it uses. The
# drape first: with the garment it is the longer chain (CPU seconds in a fresh clone, one part
# after another: drape 54 and garment 15, sheet 45 and hanging 28), so neither waits on the sheet.
DEMO_PARTS := demo-drape demo-sheet demo-hanging demo-garment
.PHONY: $(DEMO_PARTS)

demo: $(VENV)/.installed-plot
	mkdir -p demo-out
	$(MAKE) --no-print-directory -j2 --output-sync=target $(DEMO_PARTS)
	@echo "open demo-out/*.xdmf in ParaView; figures: demo-out/hanging_sheet.png, demo-out/drape.png,"
	@echo "demo-out/garment.png and the movie in demo-out/garment-render/ (movie.mp4, or movie.gif)"

demo-sheet:
	$(CLOTHTOOL) analyze sample_data/sheet -o demo-out/sheet.h5
	$(CLOTHTOOL) analyze sample_data/sheet -o demo-out/sheet_3d.h5 --reference first --kabsch -q
	$(CLOTHTOOL) info demo-out/sheet_3d.h5 | head -20

demo-hanging:
	$(CLOTHTOOL) simulate sample_data/hanging_sheet.yaml -o demo-out/hanging_sheet
	$(CLOTHTOOL) analyze demo-out/hanging_sheet -o demo-out/hanging_sheet.h5 --reference uv
	$(CLOTHTOOL) plot demo-out/hanging_sheet.h5 -o demo-out/hanging_sheet.png

demo-drape:
	$(CLOTHTOOL) simulate sample_data/drape.yaml -o demo-out/drape
	$(CLOTHTOOL) analyze demo-out/drape -o demo-out/drape.h5 --reference uv -q
	$(CLOTHTOOL) plot demo-out/drape.h5 -o demo-out/drape.png

demo-garment: demo-drape
	$(CLOTHTOOL) simulate sample_data/garment.yaml -o demo-out/garment
	$(CLOTHTOOL) analyze demo-out/garment -o demo-out/garment.h5 --reference uv -q
	$(CLOTHTOOL) render demo-out/garment -o demo-out/garment-render -q
	cp demo-out/garment-render/frame_00045.png demo-out/garment.png

test: $(VENV)/.installed-test
	$(PY) -m pytest -q

bench: $(VENV)/.installed-bench
	$(PY) -m benchmarks

clean:
	rm -rf demo-out bench-results .pytest_cache .hypothesis
