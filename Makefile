# The two commands of the README: `make demo` and `make test`.
# Both create the virtual environment .venv on first use and install the pinned dependencies.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test test-slow lint clean bench mpi

$(STAMP): pyproject.toml requirements-nodeps.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-compile -e '.[dev]'
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-deps \
		-r requirements-nodeps.txt
	# every installed module and the package byte-compiled (10 s on 2 cores): where Python
	# writes no caches (PYTHONDONTWRITEBYTECODE, set where this project is developed) each
	# process would compile them from source again -- a second of `pymorembs --help` alone
	$(BIN)/python -c "import compileall, sysconfig; \
		compileall.compile_dir(sysconfig.get_paths()['purelib'], quiet=2, workers=0); \
		compileall.compile_dir('src', quiet=2, workers=0)"
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
# The fast solver (MKL PARDISO) is a main dependency on x86-64 Linux: nothing extra to install.
FLOOR_DOFS   ?= 35000 300000
PEERS_DOFS   ?= 10000
GRAMIAN_DOFS ?= 10000 35000
REFERENCE_DOFS ?= 10000 35000
SCALING_DOFS ?= 35000 70000 150000 300000
READ_DOFS    ?= 35000 300000
SOLVER_DOFS  ?= 35000 150000

bench: $(STAMP)
	$(BIN)/python bench/solvers.py --dofs $(SOLVER_DOFS)
	$(BIN)/python bench/floor_ratio.py --method krylov soaga --model rack-solid tet10-box --dofs $(FLOOR_DOFS)
	$(BIN)/python bench/peers.py --dofs $(PEERS_DOFS)
	for n in $(GRAMIAN_DOFS); do $(BIN)/python bench/large_gramian.py --dofs $$n || exit 1; done
	$(BIN)/python bench/reference.py --dofs $(REFERENCE_DOFS)
	$(BIN)/python bench/scaling.py --dofs $(SCALING_DOFS)
	$(BIN)/python bench/read_speed.py --dofs $(READ_DOFS) --repeat 2

# The optional distributed solver (docs/performance.md, "Distributed backend"): Debian 12's MUMPS
# 5.5.1 and Open MPI 4.1, serial OpenBLAS for MUMPS's dense fronts (it becomes the system's BLAS in
# place of the reference BLAS), and mpi4py in the venv. Needs root: `make mpi SUDO=sudo`.
SUDO ?=
mpi: $(STAMP)
	$(SUDO) apt-get install -y --no-install-recommends libmumps-dev=5.5.1-1 openmpi-bin \
		libopenmpi-dev libopenblas0-serial
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-compile -e '.[mpi]'

clean:
	rm -rf $(VENV) out build src/*.egg-info
