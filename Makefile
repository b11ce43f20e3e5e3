# The two commands of the README: `make demo` and `make test`.
# Both create the virtual environment .venv on first use and install the pinned dependencies.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test lint clean

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

test: $(STAMP)
	$(BIN)/python -m pytest -q

lint: $(STAMP)
	$(BIN)/ruff check src tests examples
	$(BIN)/ruff format --check src tests examples

clean:
	rm -rf $(VENV) out build src/*.egg-info
