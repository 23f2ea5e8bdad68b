# Developer entry points. On a fresh machine (Python >= 3.10 and a Rust toolchain):
#   make demo    build the extension into .venv; compare the baselines on the paper's scenes and
#                every task (khepera-gym demo), plots in demo_out/
#   make test    build with every extra the tests use (sb3, rllib, export, calibrate, torchrl,
#                benchmarl: torch brings ~5 GB), then run the Rust and Python tests
#   make docs    the documentation site into docs/_build/html (Sphinx, MyST, Furo)
# CI (.ci/run) then runs `make test-floors` (the Python tests at the declared floors, on Python
# 3.10), `make wheel` (the abi3 wheel, smoke-tested in a fresh venv) and `make docs`.
# Everything Python lives in the virtual environment .venv (created here when missing).

VENV      := .venv
VENV_ABS  := $(abspath $(VENV))
PYTHON    := $(VENV)/bin/python
# Runs a command as if the virtual environment were activated (maturin installs into $VIRTUAL_ENV).
IN_VENV   := VIRTUAL_ENV=$(VENV_ABS) PATH=$(VENV_ABS)/bin:$$PATH
# The extension is rebuilt only when one of these changed since the last `make develop`.
RUST_SRC  := Cargo.toml $(wildcard Cargo.lock) pyproject.toml \
             $(shell find src configs -type f 2>/dev/null)
TOOLS     := $(VENV)/.tools-installed
BUILT     := $(VENV)/.khepera-gym-built
SB3       := $(VENV)/.sb3-installed
DOCS_TOOLS := $(VENV)/.docs-installed

# The floors leg: a Python 3.10 venv whose packages are pyproject.toml's floors.
FLOORS_VENV        := .venv-floors
FLOORS_PIP         := $(FLOORS_VENV)/bin/python -m pip --disable-pip-version-check
FLOORS_PYTEST      := $(FLOORS_VENV)/bin/python -m pytest -q -p no:cacheprovider
FLOORS_CONSTRAINTS := constraints/floors.txt
FLOORS_RLLIB       := constraints/floors-rllib.txt
FLOORS_WHEEL_DIR   := $(FLOORS_VENV)/wheel
FLOORS_WHEEL        = $$(ls $(FLOORS_WHEEL_DIR)/*.whl)
# The extras of the first step: all but rllib, whose floors cannot be installed beside them.
FLOORS_EXTRAS      := test,sb3,render,export,calibrate,torchrl,benchmarl,report
# A Python 3.10 interpreter: FLOORS_PYTHON=... if given, else python3.10 on PATH, else one of
# pyenv's 3.10 (each candidate is run to check it is 3.10: a pyenv shim may not be usable).
PYENV_ROOT         ?= $(HOME)/.pyenv
is_python310        = $(shell $(1) -c "import sys; sys.exit(sys.version_info[:2] != (3, 10))" \
                        >/dev/null 2>&1 && echo $(1))
FLOORS_CANDIDATES   = python3.10 $(wildcard $(PYENV_ROOT)/versions/3.10*/bin/python3.10)
FLOORS_PYTHON      ?= $(firstword $(foreach candidate,$(FLOORS_CANDIDATES), \
                        $(call is_python310,$(candidate))))

.PHONY: develop test test-floors demo bench lint format clean wheel docs configs generated

develop: $(BUILT)

$(PYTHON):
	python3 -m venv $(VENV)

$(TOOLS): $(PYTHON)
	$(PYTHON) -m pip install --quiet "maturin>=1.5,<2"
	touch $@

# `maturin develop` installs the package's dependencies and its `test` extra (pytest, ruff), puts
# the compiled `_core` into khepera_gym/ and links the source folder into .venv (editable), so
# changes to Python files need no rebuild.
$(BUILT): $(TOOLS) $(RUST_SRC)
	$(IN_VENV) $(VENV)/bin/maturin develop --release --extras test
	touch $@

# `make test` also installs the `sb3` extra (stable-baselines3, torch, rich) for tests/test_sb3.py
# and the `rllib` extra (ray[rllib]) for tests/test_rllib.py, the `export` extra (onnx,
# onnxruntime) for tests/test_export.py, the `calibrate` extra (scipy) for tests/test_calibrate.py
# and the `torchrl` and `benchmarl` extras for
# tests/test_torchrl.py, and the `typecheck` extra (mypy, basedpyright: ~60 MB) for
# tests/test_static_types.py, and the `report` extra (rliable) for the benchmark's aggregate
# statistics, with the same `maturin develop` (and stamps the build as fresh). PyPI's
# torch wheel brings its CUDA libraries: about 5.4 GB and 75 s on a fresh machine; Ray RLlib adds
# about 0.7 GB and 60 s, onnx and onnxruntime about 110 MB, torchrl and BenchMARL ~160 MB and
# ~10 s. Ray pins its gymnasium version, so the tests then run with that one. `make demo` does
# without them.
$(SB3): $(TOOLS) pyproject.toml
	$(IN_VENV) $(VENV)/bin/maturin develop --release --extras test,sb3,rllib,export,calibrate,torchrl,benchmarl,typecheck,report
	touch $@ $(BUILT)

test: $(SB3) develop
	cargo test --release
	$(PYTHON) -m pytest -q

# The Python tests at the declared floors on Python 3.10 (`make test` runs them on 3.11 with the
# newest releases), in two steps that tests/test_dependencies.py knows by KHEPERA_GYM_FLOORS:
# 1. pip installs the project's wheel with every extra but rllib, held to constraints/floors.txt,
#    and the whole suite runs (tests/test_rllib.py skips itself);
# 2. Ray 2.52, the rllib extra's floor, pins gymnasium 1.1.1 and needs protobuf >= 3.20.3, which
#    onnx 1.12 (the export extra's floor) refuses: the same venv drops onnx and onnxruntime, takes
#    the rllib extra held to constraints/floors-rllib.txt, and tests/test_rllib.py runs.
# The wheel's build reuses the extension `make develop` compiled (abi3: one build serves every
# CPython >= 3.10). The tests import the source tree with that extension, as `make test` does
# (`khepera-gym train` finds configs/hyperparams/ there). The stamp marks the venv as step 1's:
# step 2 removes it, so the next run rebuilds the venv (~2 min; ~5.5 GB with torch 2.3's CUDA
# libraries), as does a change of the pins.
$(FLOORS_VENV)/.floors-installed: $(FLOORS_CONSTRAINTS) pyproject.toml $(TOOLS) | $(BUILT)
	@test -n "$(FLOORS_PYTHON)" || { echo "make test-floors needs a Python 3.10 interpreter:" \
	  "none found as python3.10 on PATH nor as $(PYENV_ROOT)/versions/3.10*/bin/python3.10;" \
	  "install one (pyenv install 3.10) or pass FLOORS_PYTHON=/path/to/python3.10" >&2; exit 1; }
	rm -rf $(FLOORS_VENV)
	$(FLOORS_PYTHON) -m venv $(FLOORS_VENV)
	$(IN_VENV) $(VENV)/bin/maturin build --release --out $(FLOORS_WHEEL_DIR)
	$(FLOORS_PIP) install --quiet --constraint $(FLOORS_CONSTRAINTS) \
	  "$(FLOORS_WHEEL)[$(FLOORS_EXTRAS)]"
	$(FLOORS_PIP) check
	touch $@

test-floors: develop $(FLOORS_VENV)/.floors-installed
	KHEPERA_GYM_FLOORS=floors $(FLOORS_PYTEST)
	rm $(FLOORS_VENV)/.floors-installed
	$(FLOORS_PIP) uninstall --quiet --yes onnx onnxruntime
	$(FLOORS_PIP) install --quiet --constraint $(FLOORS_RLLIB) "$(FLOORS_WHEEL)[rllib]"
	$(FLOORS_PIP) check
	KHEPERA_GYM_FLOORS=rllib $(FLOORS_PYTEST) tests/test_rllib.py tests/test_dependencies.py

demo: develop
	$(VENV)/bin/khepera-gym demo

bench: develop
	$(PYTHON) examples/benchmark.py

# The docs extra's packages (Sphinx, MyST, Furo), read from pyproject.toml and installed with pip
# beside the built extension (no rebuild).
$(DOCS_TOOLS): pyproject.toml $(TOOLS)
	$(PYTHON) -c "import tomllib; print('\n'.join(tomllib.load(open('pyproject.toml', 'rb'))['project']['optional-dependencies']['docs']))" > $(VENV)/docs-requirements.txt
	$(PYTHON) -m pip install --quiet -r $(VENV)/docs-requirements.txt
	touch $@

# The site, into docs/_build/html, from a clean state: docs/conf.py first writes the generated
# pages (docs/generated/: every env, scene, sensor, baseline, and the results tables from
# docs/results/) from the code. Warnings are errors (-W, all reported with --keep-going) and
# every cross-reference must resolve (-n): a broken internal link, a missing page or label, a
# stale include fails the build.
docs: develop $(DOCS_TOOLS)
	rm -rf docs/_build docs/generated
	$(PYTHON) -m sphinx -W --keep-going -n -q -b html docs docs/_build/html
	@echo "docs: open docs/_build/html/index.html"

# Every task's default scenario file, configs/<task>.toml, written from the core's declarations
# (the files are what the docs point users to; tests/test_scenarios.py checks they are current).
configs: develop
	$(PYTHON) -m khepera_gym.analysis.docgen --configs configs

# The generated source (khepera_gym/_generate.py): a PettingZoo module file for each family and
# behaviour version, the import blocks of pettingzoo/ and envs/, the vector env classes. Run it
# after adding a task, a version or a family; tests/test_generated.py fails while it is due.
generated: develop
	$(PYTHON) -m khepera_gym._generate

# Clippy runs twice: the binding (src/python/) is compiled only with the `python` feature.
lint: develop
	cargo fmt --check
	cargo clippy --release -- -D warnings
	cargo clippy --release --features python -- -D warnings
	$(VENV)/bin/ruff check khepera_gym tests examples benchmarks
	$(VENV)/bin/ruff format --check khepera_gym tests examples benchmarks

format: develop
	cargo fmt
	$(VENV)/bin/ruff format khepera_gym tests examples benchmarks
	$(VENV)/bin/ruff check --fix khepera_gym tests examples benchmarks

clean:
	rm -rf $(BUILT) demo_out docs/_build docs/generated
	rm -f khepera_gym/_core*.so khepera_gym/_core*.pyd

# An abi3 wheel (one wheel for every CPython >= 3.10) and the sdist in dist/, then a smoke test:
# the wheel installed in a fresh venv, run with no Rust toolchain on PATH. Both must carry
# Cargo.toml's version, in their names and as khepera_gym.__version__ (tests/test_release.py).
wheel: $(TOOLS)
	rm -rf dist
	$(IN_VENV) $(VENV)/bin/maturin build --release --out dist
	$(IN_VENV) $(VENV)/bin/maturin sdist --out dist
	python3 -m venv dist/smoke-venv
	dist/smoke-venv/bin/pip install --quiet dist/*.whl
	cd dist && env PATH=/usr/bin:/bin smoke-venv/bin/python -c "import gymnasium as gym, khepera_gym; \
	e = gym.make('KheperaIV-Avoid-v1', render_mode='rgb_array'); o, _ = e.reset(seed=0); \
	o, r, t, u, i = e.step(e.action_space.sample()); f = e.render(); \
	print('wheel smoke test ok:', khepera_gym.__version__, o.shape, f.shape)"
	version=$$($(PYTHON) -c "import tomllib; print(tomllib.load(open('Cargo.toml', 'rb'))['package']['version'])"); \
	ls dist/khepera_gym-$$version-*.whl dist/khepera_gym-$$version.tar.gz && \
	cd dist && smoke-venv/bin/python -c "import khepera_gym, sys; v = khepera_gym.__version__; \
	sys.exit(0 if v == '$$version' else f'the wheel says {v}, Cargo.toml $$version')"
