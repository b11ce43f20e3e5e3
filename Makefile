# The two commands of the README: `make demo` and `make test`.
# Both create the virtual environment .venv on first use and install the pinned dependencies.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test test-slow lint clean bench

$(STAMP): pyproject.toml requirements-nodeps.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[dev]'
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-deps \
		-r requirements-nodeps.txt
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/pymorembs example rack-beams --out out/demo/model
	$(BIN)/pymorembs info out/demo/model/model.h5 --modes 12
	$(BIN)/pymorembs reduce examples/rack-beams-demo.toml --out out/demo

# `make test`: everything but the slow end-to-end cases (under 5 min on 2 cores);
# `make test-slow`: those (CI runs both).
test: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow"

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

lint: $(STAMP)
	$(BIN)/ruff check src tests examples bench fuzz
	$(BIN)/ruff format --check src tests examples bench fuzz

# Benchmarks of issue #6 (bench/README.md), about 1-2 h on 2 cores; results in bench/RESULTS.md.
# Installs the optional fast solver extra `.[fast]` when pyproject.toml defines it.
FLOOR_DOFS   ?= 35000 300000
PEERS_DOFS   ?= 10000
GRAMIAN_DOFS ?= 10000 35000
REFERENCE_DOFS ?= 10000 35000
SCALING_DOFS ?= 35000 70000 150000 300000
READ_DOFS    ?= 35000 300000

bench: $(STAMP)
	@if grep -Eq '^fast *=' pyproject.toml; then \
		$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[fast]' \
		|| echo "bench: could not install .[fast]; measuring with the solvers installed"; \
	else \
		echo "bench: pyproject.toml has no [fast] extra; measuring with the solvers installed"; \
	fi
	$(BIN)/python bench/floor_ratio.py --method krylov soaga --model rack-solid tet10-box --dofs $(FLOOR_DOFS)
	$(BIN)/python bench/peers.py --dofs $(PEERS_DOFS)
	for n in $(GRAMIAN_DOFS); do $(BIN)/python bench/large_gramian.py --dofs $$n || exit 1; done
	$(BIN)/python bench/reference.py --dofs $(REFERENCE_DOFS)
	$(BIN)/python bench/scaling.py --dofs $(SCALING_DOFS)
	$(BIN)/python bench/read_speed.py --dofs $(READ_DOFS) --repeat 2

clean:
	rm -rf $(VENV) out build src/*.egg-info
