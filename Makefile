# vpcontact: setup, demo, tests.  `make help` lists the targets.
SHELL := /bin/bash
.DEFAULT_GOAL := help

VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.vpcontact-installed
# the linter's version is pinned: a newer ruff may add findings to the same rule set
RUFF_VERSION := 0.17.6
CASE   ?= cases/wang_cheng_2021.yaml

# Debian bookworm packages (the platform is fixed: dolfinx 0.5.2 from Debian).
DEB_PACKAGES := python3-dolfinx-real python3-petsc4py-real python3-mpi4py python3-gmsh gmsh \
                python3-yaml python3-jsonschema python3-numpy python3-pytest python3-venv \
                python3-pip python3-setuptools python3-wheel python3-dev openmpi-bin \
                python3-h5py python3-matplotlib python3-hypothesis libopenblas0-pthread \
                libsuitesparse-dev python3-threadpoolctl libmumps-dev \
                libegl1 libegl-mesa0 libgl1 libglx-mesa0 python3-sphinx python3-myst-parser
# pyvista (off-screen pictures through EGL, no display needed) and its VTK are not Debian
# bookworm packages (python3-vtk9 is VTK 9.1, older than pyvista needs): from PyPI, pinned.
PYVISTA := pyvista==0.49.1 vtk==9.7.2

# libopenblas0-pthread replaces the reference BLAS (Debian alternatives): MUMPS factorisation
# 2.7x faster at 33k dofs (measured); one thread, as small dense solves slow down with more.
# mpirun as root (CI and these machines run as root); small dense algebra single-threaded.
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
export OPENBLAS_NUM_THREADS := 1
export OMP_NUM_THREADS := 1

.PHONY: help setup demo test lint convergence stability bench docs clean

help:
	@echo "make setup        install Debian packages, create $(VENV), pip install -e ., pyvista and ruff"
	@echo "                  (idempotent)"
	@echo "make demo         run $(CASE) (the paper's Section 4 example) into results/"
	@echo "make test         run the test suite (serial and mpirun -n 2)"
	@echo "make lint         ruff check of app, forms, meshes, tests, demos and docs (pyproject.toml)"
	@echo "make convergence  the paper's Table 1 study (h = k = 1/8..1/64 vs 1/128) for three deltas,"
	@echo "                  and error against wall time, uniform vs run --tol 0.1, 0.05 (error_vs_wall.png)"
	@echo "make stability    stiff and extreme variants of the paper case (stability.md/.csv)"
	@echo "make bench        step solver timings (results/bench/bench.json, bench.md)"
	@echo "make docs         the documentation as HTML (Sphinx) in docs/_build/html, its case-file"
	@echo "                  reference regenerated from the schema first"
	@echo "make clean        remove results/ and .pytest_cache"
	@echo "After make setup, the commands: ./vpcontact run|check|plot|info|convergence|stability|bench"
	@echo "  (./vpcontact --help); in parallel: mpirun -n 2 ./vpcontact run CASE.yaml, as root with"
	@echo "  OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 before mpirun"

setup:
	@missing=$$(for p in $(DEB_PACKAGES); do \
	  dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q "install ok installed" || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "setup: installing Debian packages:" $$missing; \
	  apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y $$missing; \
	fi
	@# the stamp is redone when pyproject.toml changed, ruff $(RUFF_VERSION) or pyvista is missing
	@$(PY) -m ruff --version 2>/dev/null | grep -qx 'ruff $(RUFF_VERSION)' || rm -f $(STAMP)
	@$(PY) -c "import pyvista" 2>/dev/null || rm -f $(STAMP)
	@$(MAKE) --no-print-directory $(STAMP)
	@# byte-compile our modules (the editable install does not, and with PYTHONDONTWRITEBYTECODE
	@# set, as on these machines, every run would compile them again: 0.08 s, measured)
	@$(PY) -m compileall -q app forms meshes >/dev/null

$(STAMP): pyproject.toml
	[ -x $(PY) ] || /usr/bin/python3 -m venv --system-site-packages $(VENV)
	$(PY) -m pip install --quiet --no-build-isolation --no-deps -e .
	@# ruff (make lint) is not a Debian bookworm package: from PyPI.  Without network access
	@# the rest still works; the next make setup tries again.
	$(PY) -m pip install --quiet ruff==$(RUFF_VERSION) || echo "setup: warning: ruff not installed (make lint needs it)"
	$(PY) -m pip install --quiet $(PYVISTA) || { echo "setup: error: pyvista (PyPI) could not be installed: the pictures and their tests need it"; exit 1; }
	@$(PY) -c "import dolfinx, petsc4py, gmsh, yaml, jsonschema, pyvista, vpcontact; print('setup: dolfinx', dolfinx.__version__, 'pyvista', pyvista.__version__, 'ok')"
	@touch $(STAMP)

# ./vpcontact runs .venv/bin/python -m vpcontact (the README's commands use it too)
demo: setup
	./vpcontact run $(CASE) --overwrite

test: setup
	$(PY) -m pytest -ra tests

lint: setup
	$(PY) -m ruff check app forms meshes tests demos docs

# The paper's Table 1 configuration, for the default delta and two larger ones (work-precision
# view across the friction regularisation). Runs are cached in the run cache: $VPCONTACT_CACHE,
# else $XDG_CACHE_HOME/vpcontact, else ~/.cache/vpcontact (./vpcontact info names it).
# --adaptive: then run --tol to each CONV_TOLS from h = k = 1/8 with the first delta, and
# error_vs_wall.csv/.png (error against wall time, uniform vs adaptive). Measured: 432 s
# from an empty run cache on a loaded machine (--tol 0.01's 13 passes under the case's SNES VI
# 372 s of it); CONV_TOLS="0.1 0.05": 62 to 101 s.
CONV_DELTAS ?= 1e-7 1e-3 1e-2
CONV_TOLS ?= 0.1 0.05 0.01
convergence: setup
	./vpcontact convergence $(CASE) --levels 8 16 32 64 --reference 128 --vary both \
	  --deltas $(CONV_DELTAS) --adaptive $(CONV_TOLS) --overwrite

stability: setup
	./vpcontact stability $(CASE) --overwrite

bench: setup
	./vpcontact bench $(CASE)

# the case-file reference (docs/case-file.md) from the schema, then the HTML: -W, a warning is an
# error (tests/unit/test_docs.py runs the same build)
docs: setup
	$(PY) -m vpcontact.case.reference docs/case-file.md
	$(PY) -m sphinx -W --keep-going -q -b html -d docs/_build/doctrees docs docs/_build/html
	@echo "docs: docs/_build/html/index.html"

clean:
	rm -rf results .pytest_cache
