# meshmill: `make demo` and `make test` are all a new user needs.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
DATA   := src/meshmill/data

.PHONY: venv demo test bench bench-3axis clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q -e '.[dev]'
	touch $(STAMP)

demo: venv
	$(BIN)/meshmill finish $(DATA)/vase.stl --tools $(DATA)/tools.toml --step-down 1 --out demo-out
	$(BIN)/meshmill verify $(DATA)/vase.stl demo-out/toolpath.cl --tools $(DATA)/tools.toml --out demo-out/verify.json
	@echo "demo results in demo-out/ (toolpath.cl, summary.json, verify.json)"

test: venv
	$(BIN)/python -m pytest

bench: venv
	$(BIN)/python bench/finish_tableau7.py

bench-3axis: venv
	$(BIN)/python bench/three_axis_vs_ocl.py

clean:
	rm -rf $(VENV) demo-out bench/out .pytest_cache
