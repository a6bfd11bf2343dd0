# pfmembrane: `make` lists the targets.
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
NP ?= 2
export PETSC_DIR ?= /usr/lib/petscdir/petsc3.18/x86_64-linux-gnu-real
export SLEPC_DIR ?= /usr/lib/slepcdir/slepc3.18/x86_64-linux-gnu-real
export OMPI_ALLOW_RUN_AS_ROOT = 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM = 1
export OMPI_MCA_rmaps_base_oversubscribe = 1
export OMPI_MCA_btl_vader_single_copy_mechanism = none
# One BLAS thread per process: the batched products are small, and two threads per process
# on 2 cores spin (runs/atlas/notes.md: one rank 47.0 s against 57.7 s).
export OPENBLAS_NUM_THREADS ?= 1
MPIEXEC ?= mpiexec
DEB := python3-petsc4py python3-slepc4py python3-mpi4py python3-h5py python3-scipy python3-numpy \
       python3-matplotlib python3-venv python3-pip openmpi-bin

.PHONY: help install run check test test-fast test-1 test-2 tables adapt adapt-discocyte adapt-dumbbell \
        adapt-12271 adapt-24597 adapt-dumbbell-12271 adapt-dumbbell-12271-half adapt-24597-half adapt-discocyte-half table4 atlas phase-diagram sharp-diagram pears bench bench-basis bench-scenes branches figures extremes limits clean

help:
	@echo "make install  Debian PETSc/petsc4py/MPI/h5py + a venv with pfmembrane"
	@echo "make run      the default scene (options/discocyte.opts) on $(NP) ranks"
	@echo "make check    a 30 s smoke run on 2 ranks"
	@echo "make test     the test suite: serial tests, then the MPI tests on 2 ranks"
	@echo "make test-fast  the quick serial tests (not marked slow or mpi), under a minute"
	@echo "make tables   the paper's uniform-grid tables (1, 2) under runs/tables/"
	@echo "make adapt-discocyte | adapt-dumbbell  the adaptive 6,124-node sequences (Tables 3, 5)"
	@echo "make adapt-12271 | adapt-24597  the finer adaptive discocyte sequences (Table 4)"
	@echo "make adapt-dumbbell-12271  the dumbbell on 12,271 adapted nodes, to eps 0.007"
	@echo "make adapt-discocyte-half  the 6,124-node discocyte sequence on the half box"
	@echo "make adapt-dumbbell-12271-half  the 12,271-node dumbbell sequence on the half box, to eps 0.01"
	@echo "make adapt-24597-half  the 24,597-node discocyte sequence on the half box, to eps 0.005"
	@echo "make adapt    all five sequences, tables under runs/adapt/"
	@echo "make table4   Table 4 from the discocyte sequences' checkpoints (runs/adapt/table4.md)"
	@echo "make bench    speed/accuracy of full solves under runs/bench/ (solve.md, pareto.png)"
	@echo "make bench-basis  set-up time, size and memory of the max-ent basis (runs/bench/basis.md)"
	@echo "make bench-scenes half box and auto box against the paper box (runs/bench/scenes.md)"
	@echo "make branches  oblate and prolate branches, v = 0.95 -> 0.65 (Figure 6), runs/branches/"
	@echo "make figures  the README's figures from existing checkpoints, runs/figures/index.md"
	@echo "make extremes  stability study (eps, gamma, v, C0, box, graded grids), runs/extremes/extremes.md"
	@echo "make limits   the Clifford torus, symmetric budding and the split as eps falls, runs/limits/"
	@echo "make crossings  the c0 = 0 prolate-oblate and oblate-stomatocyte crossings, runs/crossings/"
	@echo "make pears    the prolate's pear bifurcation in c0 at v 0.8 per eps, against the sharp D_pe line (runs/pears)"
	@echo "make atlas    every family continued in v at c0 = -1 ... 2.5, eps 0.01 where 0.02 fails, the merged diagram in runs/atlas/merged"
	@echo "make phase-diagram  the phase-field diagram by -pf_tol at every (c0, v), beside the sharp one: runs/phase_diagram/diagram.md"
	@echo "make sharp-diagram  the sharp solver's phase diagram over the atlas's c0 and v, runs/sharp_diagram/diagram.md"

$(PY):
	@if ! /usr/bin/python3 -c 'import petsc4py, slepc4py, mpi4py, h5py, scipy, matplotlib' 2>/dev/null; then \
	  if command -v apt-get >/dev/null && [ "$$(id -u)" = 0 ]; then \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(DEB); \
	  elif command -v apt-get >/dev/null && command -v sudo >/dev/null; then \
	    sudo apt-get update -qq && sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(DEB); \
	  else \
	    echo "pfmembrane needs petsc4py, mpi4py, h5py, numpy, scipy, matplotlib."; \
	    echo "Without apt: conda install -c conda-forge petsc4py mpi4py h5py scipy matplotlib,"; \
	    echo "or: PETSC_CONFIGURE_OPTIONS='--with-cuda=0 --download-mumps ...' pip install --no-cache-dir petsc petsc4py"; \
	    exit 1; \
	  fi; \
	fi
	/usr/bin/python3 -m venv --system-site-packages $(VENV)
	$(PY) -m pip install -q -e '.[test]'

# Debian's petsc4py and slepc4py are found through PETSC_DIR and SLEPC_DIR; the venv
# finds them by a .pth of its own.
PTH := $(VENV)/pfmembrane-petsc4py.stamp
$(PTH): $(PY)
	site=$$($(PY) -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])'); \
	  /usr/bin/python3 -c 'import os, petsc4py, slepc4py; [print(os.path.dirname(os.path.dirname(m.__file__))) for m in (petsc4py, slepc4py)]' > "$$site/pfmembrane-petsc4py.pth"
	touch $@

# An mpiexec that lets Open MPI run as root and with more ranks than cores.
$(VENV)/bin/mpiexec: $(PY)
	m=$$(command -v mpiexec); case "$$m" in *$(VENV)*) m=/usr/bin/mpiexec;; esac; \
	  printf '%s\n' '#!/bin/sh' \
	  'export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1' \
	  'export OMPI_MCA_rmaps_base_oversubscribe=1 OMPI_MCA_btl_vader_single_copy_mechanism=none' \
	  "exec $$m \"\$$@\"" > $@
	chmod +x $@

install: $(PY) $(PTH) $(VENV)/bin/mpiexec

run: install
	$(MPIEXEC) -n $(NP) $(PY) -m pfmembrane -options_file options/discocyte.opts

check: install
	$(MPIEXEC) -n 2 $(PY) -m pfmembrane -options_file options/discocyte.opts \
	  -pf_nodes 3000 -pf_eps 0.06 -pf_output runs/check.h5

# Two test files at a time (pytest-xdist), each file's tests in order on one worker.
test: install
	$(PY) -m pytest -q -n 2 --dist loadfile tests
	$(MPIEXEC) -n 2 $(PY) -m pytest -q tests/parallel

# No application runs and no mpiexec with more than one rank (markers in tests/conftest.py).
test-fast: install
	$(PY) -m pytest -q -m 'not slow and not mpi' tests

tables: install
	$(PY) runs/tables/tables.py --np $(NP) --out runs/tables

SEQUENCE = $(PY) runs/adapt/sequence.py --np $(NP)
adapt-discocyte: install
	$(SEQUENCE) options/adapt/discocyte --scene options/discocyte.opts
adapt-dumbbell: install
	$(SEQUENCE) options/adapt/dumbbell --scene options/dumbbell.opts
adapt-12271: install
	$(SEQUENCE) options/adapt/discocyte_12271 --scene options/discocyte.opts
adapt-24597: install
	$(SEQUENCE) options/adapt/discocyte_24597 --scene options/discocyte.opts
adapt-dumbbell-12271: install
	$(SEQUENCE) options/adapt/dumbbell_12271 --scene options/dumbbell.opts
adapt-discocyte-half: install
	$(SEQUENCE) options/adapt/discocyte_half --scene options/discocyte.opts
adapt-dumbbell-12271-half: install
	$(SEQUENCE) options/adapt/dumbbell_12271_half --scene options/dumbbell.opts
adapt-24597-half: install
	$(SEQUENCE) options/adapt/discocyte_24597_half --scene options/discocyte.opts
adapt: adapt-discocyte adapt-dumbbell adapt-12271 adapt-24597 adapt-dumbbell-12271

TABLE4_SEQUENCES = $(addprefix options/adapt/,discocyte discocyte_half discocyte_12271 \
                   discocyte_24597 discocyte_24597_half)
table4: install
	$(PY) runs/adapt/table4.py $(TABLE4_SEQUENCES) --out runs/adapt/table4.md

bench: install
	$(PY) runs/bench/bench.py solve --out runs/bench

bench-basis: install
	$(PY) runs/bench/bench.py basis --out runs/bench

bench-scenes: install
	$(PY) runs/bench/economy.py --out runs/bench --np $(NP)

# Both branches run even if one stops early; the target fails if either did. A restarted step
# starts near its answer, so stage 1 stops after one iteration at its default constraint
# residual (1e-3); from there stage 2 does not converge at the prolate v = 0.65. It does after
# a tighter stage 1.
BRANCH = $(PY) runs/branches/branch.py --np $(NP) --from 0.95 --to 0.65 --step 0.05 --out runs/branches
BRANCH_OPTIONS = -- -pf_stage1_rtol 1e-5
branches: install
	@status=0; \
	$(BRANCH) --branch oblate $(BRANCH_OPTIONS) || status=1; \
	$(BRANCH) --branch prolate $(BRANCH_OPTIONS) || status=1; \
	$(PY) runs/branches/branch.py --plot runs/branches && exit $$status

figures: install
	$(PY) runs/figures/figures.py --out runs/figures

extremes: install
	$(PY) runs/extremes/extremes.py --np $(NP) --out runs/extremes

limits: install
	$(PY) runs/limits/limits.py --np $(NP) --out runs/limits

pears: install
	$(PY) runs/pears/pears.py --sharp --out runs/pears
	$(PY) runs/pears/pears.py --np $(NP) --v 0.8 --out runs/pears $(FORCE)

clean:
	rm -rf $(VENV) runs/check.h5

crossings: install
	$(PY) runs/crossings/crossings.py --np $(NP) --eps 0.01 --nodes 84000 --branch stomatocyte oblate prolate --out runs/crossings

# The atlas's branches keep in runs/atlas/branches: a second run redraws from them; FORCE=--force
# follows them again. Below the oblate fold of eps 0.02 the diagram needs eps 0.01
# (runs/atlas/notes.md): the oblate and stomatocyte families at c0 <= 0 in atlases of their
# own, and the pears (full box) in a third, merged with the first into runs/atlas/merged.
atlas: install
	$(PY) runs/atlas/atlas.py --np $(NP) --groups $(NP) --eps 0.02 --nodes 25000 --ds 0.05 --out runs/atlas $(FORCE)
	$(PY) runs/atlas/atlas.py --np $(NP) --groups 1 --eps 0.01 --nodes 84000 --ds 0.15 --steps 120 --families oblate --c0 -1 -0.5 0 --out runs/atlas/oblate $(FORCE)
	$(PY) runs/atlas/atlas.py --np $(NP) --groups $(NP) --eps 0.01 --nodes 84000 --ds 0.15 --steps 40 --families stomatocyte --c0 -1 -0.5 0 --out runs/atlas/stomatocyte $(FORCE)
	$(PY) runs/atlas/atlas.py --np $(NP) --groups 1 --eps 0.02 --nodes 25000 --ds 0.2 --steps 120 --families pear --c0 2.5 --out runs/atlas/pear_eps0.02 $(FORCE)
	$(PY) runs/atlas/atlas.py --merge runs/atlas runs/atlas/oblate runs/atlas/stomatocyte runs/atlas/pear_eps0.02 --out runs/atlas/merged

# The phase fields by accuracy on demand at every (c0, v), beside the sharp diagram below.
phase-diagram: install
	$(VENV)/bin/mpiexec -n $(NP) $(PY) runs/phase_diagram/diagram.py

# The same diagram by the sharp solver (branches continued in v, crossings solved to 1e-10).
sharp-diagram: install
	$(PY) runs/sharp_diagram/diagram.py
