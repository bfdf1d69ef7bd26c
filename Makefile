# meshmill: `make demo` and `make test` are all a new user needs.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
DATA   := src/meshmill/data

.PHONY: venv demo test bench bench-3axis bench-dexel bench-plunge bench-rough bench-gpu bench-choice bench-post bench-safety bench-startup clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q -e '.[dev,report,optimise,cluster]'
	touch $(STAMP)

demo: venv
	$(BIN)/meshmill job $(DATA)/vase-job.toml --out demo-out/job
	$(BIN)/meshmill verify $(DATA)/vase.stl demo-out/job/program.nc --machine table-table-ac --tools $(DATA)/tools.toml --tolerance 0.015 --out demo-out/job/verify-program.json --quiet
	$(BIN)/meshmill finish $(DATA)/vase.stl --tools $(DATA)/tools.toml --step-down 1 --out demo-out
	$(BIN)/meshmill verify $(DATA)/vase.stl demo-out/toolpath.cl --tools $(DATA)/tools.toml --out demo-out/verify.json
	$(BIN)/meshmill rough $(DATA)/vase.stl --tools $(DATA)/tools.toml --tool F10L --engagement 2.5 --step-down 10 --stock box --out demo-out/rough --quiet
	$(BIN)/meshmill waterline $(DATA)/vase.stl --tools $(DATA)/tools.toml --tool B4 --step-down 2 --out demo-out/waterline
	$(BIN)/meshmill raster $(DATA)/vase.stl --tools $(DATA)/tools.toml --tool R6 --scallop 0.01 --angle 45 --out demo-out/raster
	$(BIN)/meshmill simulate --design $(DATA)/vase.stl --allowance 0.5 --toolpath demo-out/toolpath.cl --tools $(DATA)/tools.toml --step 0.2 --out demo-out/simulate
	$(BIN)/meshmill feeds --design $(DATA)/vase.stl --stock offset:0.5 --toolpath demo-out/toolpath.cl --tools $(DATA)/tools.toml --material aluminium-6061 --machine table-table-ac --out demo-out/feeds
	$(BIN)/meshmill post demo-out/toolpath.cl --machine table-table-ac --tools $(DATA)/tools.toml --clearance 75 --out demo-out/program-ac.nc
	$(BIN)/meshmill verify $(DATA)/vase.stl demo-out/program-ac.nc --machine table-table-ac --tools $(DATA)/tools.toml --tolerance 0.015 --out demo-out/verify-program.json
	$(BIN)/meshmill choose rubio --tool-pair 10,2 --scallop 0.01 --zones 3 --axes 3+2 --machine seed-002 --out demo-out/choose
	$(BIN)/meshmill time demo-out/choose/toolpath.cl --machine seed-002 --tools demo-out/choose/tools.toml
	$(BIN)/meshmill report demo-out demo-out/rough demo-out/waterline demo-out/raster demo-out/simulate demo-out/feeds demo-out/choose --out demo-out/report.html
	@echo "demo results in demo-out/: job/ (the vase from a box stock: adaptive roughing from the top and then the four sides (3+2), a waterline semi-finish and a raster with rest machining, the 5-axis finish; per operation its path and the stock after it, program.nc with every tool change, read back and verified as verify-program.json, job.json, report.html), 5-axis finishing (toolpath.cl, summary.json, verify.json), rough/ (adaptive clearing from the box), 3-axis waterline/ and raster/, simulate/ (what the 5-axis path cuts: deviation.json, machined.stl, load.npz), feeds/ (its feeds optimised on the load of every move in aluminium: toolpath.cl, program.nc, the machining time before and after), choose/ (seed 002's Rubio surface: cutter, zones and 3+2 axes by machining time), program-ac.nc (the 5-axis path posted for an A/C trunnion, read back and verified within the path's 0.01 mm plus the post's 0.005 mm)"
	@echo "report: $(CURDIR)/demo-out/report.html (open it in any browser)"

test: venv
	$(BIN)/python -m pytest

bench: venv
	$(BIN)/python bench/finish_tableau7.py

bench-3axis: venv
	$(BIN)/python bench/three_axis_vs_ocl.py

bench-dexel: venv
	$(BIN)/python bench/dexel_seed_tables.py

bench-plunge: venv
	$(BIN)/python bench/plunge_roughing.py

bench-rough: venv  # FreeCAD's Adaptive2d as the peer: FC=folder holding its area.so (see bench/rough.py)
	$(BIN)/python bench/rough.py $(if $(FC),--fc $(FC))

bench-gpu: venv
	$(BIN)/python bench/gpu.py

bench-choice: venv
	$(BIN)/python bench/choice_seed_tables.py

bench-post: venv
	$(BIN)/python bench/post_programs.py

bench-safety: venv
	$(BIN)/python bench/safety.py

bench-startup: venv
	$(BIN)/python bench/startup.py

clean:
	rm -rf $(VENV) demo-out bench/out .pytest_cache
