# Set-up and entry points. `make run` and `make test` install what is missing first.
# Debian's interpreter and packages (PETSc 3.18, petsc4py, mpi4py, h5py, Open MPI); a venv
# that sees them; CalculiX (ccx: runs/compare_calculix.py, two bodies against its mortar
# contact); pymetis (METIS where PETSc lacks ParMETIS) and clarabel (tests) from PyPI.

SYSPY    ?= /usr/bin/python3
VENV     ?= .venv
PY       := $(VENV)/bin/python
STAMP    := $(VENV)/.installed
NP       ?= 2
#: make run's scene: the paper's beam with the 27-node element at N = 12, more accurate than
#: the paper's Q1 at Nd = 40 in max |u|, the contact force and the energy with 1/4 of its
#: unknowns (runs/results/estimate.md, report.md); its levels 3, 6, 12 are in the asymptotic
#: range for all three (at 2, 4, 8 max |u| is not): the run estimates its own error in each;
#: ARGS="-nd 10" runs the paper's Q1
ARGS     ?= -element q2 -nd 12 -newton_converged_reason
#: what make run / run2 write before ARGS (ARGS can override it: the last one wins)
RUN_OPTS ?= -output_formats h5,xdmf,json,png
DEB_PKGS := python3-petsc4py python3-mpi4py python3-h5py python3-yaml python3-scipy \
            python3-matplotlib python3-pytest python3-venv python3-pip openmpi-bin \
            calculix-ccx
PIP_PKGS := pymetis clarabel gmsh
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
export OMPI_MCA_rmaps_base_oversubscribe := 1
MPIRUN   := mpirun -n $(NP) --oversubscribe
#: the focused subset run on 4 ranks too (ranks without contact nodes, almost empty ranks)
TESTS4   ?= tests/test_ranks.py tests/mesh/test_transfer.py tests/solvers/test_multigrid.py \
	tests/solvers/test_jacobian.py tests/solvers/test_newton_globalisation.py \
	tests/fem/test_element.py tests/solvers/test_mixed.py tests/fem/test_quadratic.py \
	tests/solvers/test_line_smoother.py tests/fem/test_pairs.py \
	tests/fem/test_pairs_crosspoints.py tests/fem/test_pairs_lockfree.py \
	tests/fem/test_pairs_curved.py

# $(call apt_ensure,PACKAGES): install the Debian packages not installed yet (apt-get update
# only when one is missing)
apt_ensure = missing=""; for p in $(1); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
	    --no-install-recommends $$missing; \
	fi

.PHONY: install run run2 test test1 test2 test4 test-quick bench report stability validate clean help view

help:
	@echo "make run   [ARGS='-nd 10 ...']  install if needed, solve the paper's beam (q2, N = 12)"
	@echo "make test                       install if needed, run the suite on 1 and 2 ranks, tests/test_ranks.py on 4"
	@echo "make test-quick                 the suite on 1 rank without the tests marked slow (a few minutes less)"
	@echo "make view  [VIEW_DIR=runs/out/...]  ParaView (installed if needed) renders the last run -> PNGs"
	@echo "make petsc-gpu-fetch            (network) PETSc/petsc4py sdists etc. -> .gpu/dist"
	@echo "make petsc-gpu [GPU_ARGS=--cpu]  (offline) CUDA PETSc + petsc4py -> .gpu/prefix (README: GPU)"
	@echo "make test-current               the current PETSc (3.26, CPU; built once): a focused part of the suite"
	@echo "make install                    Debian packages + .venv (idempotent)"
	@echo "make bench                      speed benchmarks -> runs/results/bench.md"
	@echo "make report                     error against run time -> runs/results/report.md"
	@echo "make stability                  stability suite (edge cases) -> runs/results/stability.md"
	@echo "make validate [VALIDATE_ARGS=--quick]  Hertz / Spence validation -> runs/results/validation.md"

install: $(STAMP)

$(STAMP): setup.py Makefile
	@$(call apt_ensure,$(DEB_PKGS))
	@test -x $(PY) || $(SYSPY) -m venv --system-site-packages $(VENV)
	@# Debian's petsc4py lives under PETSc's own tree; its .pth needs the petsc-dev
	@# alternative, which we do not need, so point the venv at it directly.
	@site=$$($(PY) -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])'); \
	if ! $(PY) -c 'import petsc4py' 2>/dev/null; then \
	  d=$$(ls -d /usr/lib/petscdir/petsc3.*/x86_64-linux-gnu-real/lib/python3/dist-packages 2>/dev/null | sort -V | tail -1); \
	  test -n "$$d" || { echo "petsc4py not found"; exit 1; }; \
	  echo "$$d" > $$site/debian_petsc4py.pth; \
	fi
	@$(PY) -c 'import pymetis, clarabel, gmsh' 2>/dev/null || $(PY) -m pip install -q $(PIP_PKGS)
	@$(PY) -m pip install -q --no-deps --no-build-isolation -e .
	@$(PY) -c 'import petsc4py, mpi4py, h5py, numpy; print("ok: petsc4py", petsc4py.__version__, "numpy", numpy.__version__)'
	@touch $(STAMP)

RUN_NOTE := make run: the paper's beam with the 27-node element (-element q2) at N = 12 \
	(136,875 unknowns), more accurate than the paper's Q1 at Nd = 40 (610,203): max |u| \
	0.67 % against 0.86 %, contact force 0.061 % against 0.07 %, energy 0.048 % against \
	0.084 % (runs/results/estimate.md, report.md); it prints its own error estimate of \
	each from its levels N = 3, 6, 12. The paper's Q1: make run ARGS='-nd 10'

run: install
ifeq ($(origin ARGS),file)
	@echo "$(RUN_NOTE)"
endif
	$(PY) -m contact $(RUN_OPTS) $(ARGS)

run2: install
ifeq ($(origin ARGS),file)
	@echo "$(RUN_NOTE)"
endif
	$(MPIRUN) $(PY) -m contact $(RUN_OPTS) $(ARGS)

# ParaView renders the last run (the newest runs/out/*/solution.xdmf, or VIEW_DIR):
# contact/io/pvview.py under pvbatch checks that it finds every field of the XDMF and writes
# paraview_body.png and paraview_contact.png beside it (offscreen, in Xvfb: a 24-bit
# screen, and an auth file of our own: xvfb-run's own temporary directory sometimes fails
# its clean-up, exit status 5, after the work is done).
PV_PKGS  := paraview python3-paraview xvfb xauth
VIEW_DIR ?= $(patsubst %/solution.xdmf,%,$(firstword $(shell ls -t runs/out/*/solution.xdmf 2>/dev/null)))

view:
	@$(call apt_ensure,$(PV_PKGS))
	@test -n "$(VIEW_DIR)" && test -f "$(VIEW_DIR)/solution.xdmf" || \
	  { echo "make view: no solution.xdmf (make run first, or VIEW_DIR=DIR)"; exit 1; }
	@auth=$$(mktemp); xvfb-run -a -f $$auth -s "-screen 0 1280x1024x24" \
	  pvbatch contact/io/pvview.py $(VIEW_DIR); rc=$$?; rm -f $$auth; exit $$rc

test: install test1 test2 test4

test1: install
	$(PY) -m pytest -q tests

test2: install
	$(MPIRUN) $(PY) -m mpi4py -m pytest -q -p no:cacheprovider tests

test-quick: install
	$(PY) -m pytest -q -p no:cacheprovider -m "not slow" tests

test4: install
	mpirun -n 4 --oversubscribe $(PY) -m mpi4py -m pytest -q -p no:cacheprovider $(TESTS4)

# The current PETSc release (CPU build): PETSc + mpi4py + petsc4py from PyPI's source
# distributions by runs/petsc_gpu.sh --cpu against Debian's Open MPI and HDF5, into
# CURRENT_PREFIX (built once per machine, about 15 minutes on 2 cores; reused when present),
# then a focused part of the suite on it, on 1 and 2 ranks: the code that differs between
# 3.18 and 3.26 (contact/petsc_compat.py) and every solver path.
CURRENT_DIST   ?= .gpu/dist
CURRENT_PREFIX ?= .gpu/cpu-prefix
#: Debian's parallel HDF5 (Open MPI): solution.h5 is written through PETSc's HDF5 viewer
CURRENT_HDF5   ?= /usr/lib/x86_64-linux-gnu/hdf5/openmpi
PY_TARGET       = $(shell $(SYSPY) -c 'import sys; print("%d.%d" % sys.version_info[:2])')
TESTS_CURRENT  ?= tests/test_expression.py tests/mesh/test_mesh.py tests/mesh/test_transfer.py \
	tests/solvers/test_multigrid.py tests/solvers/test_mixed.py tests/solvers/test_jacobian.py \
	tests/solvers/test_coulomb.py tests/solvers/test_loops.py tests/fem/test_quadratic.py \
	tests/io/test_output_files.py tests/solvers/test_friction_held.py \
	tests/solvers/test_newton_globalisation.py tests/solvers/test_device_paths.py \
	tests/mesh/test_refine.py tests/fem/test_stencil.py tests/solvers/test_line_smoother.py \
	tests/fem/test_pairs.py tests/solvers/test_newton_ksp.py tests/fem/test_pairs_lockfree.py \
	tests/fem/test_pairs_curved.py tests/fem/test_pressure.py
TESTS_CURRENT2 ?= tests/test_ranks.py tests/solvers/test_multigrid.py tests/solvers/test_mixed.py \
	tests/solvers/test_coulomb.py tests/solvers/test_line_smoother.py
.PHONY: test-current petsc-current

petsc-current: install
	@$(call apt_ensure,libopenmpi-dev libhdf5-openmpi-dev)
	@test -f $(CURRENT_PREFIX)/env.sh || { \
	  PYTHON=$(SYSPY) PY_TARGET=$(PY_TARGET) runs/petsc_gpu.sh fetch $(CURRENT_DIST) && \
	  PETSC_CONFIGURE_EXTRA="--with-hdf5-dir=$(CURRENT_HDF5)" PYTHON=$(SYSPY) \
	  PY_TARGET=$(PY_TARGET) runs/petsc_gpu.sh build $(CURRENT_DIST) $(CURRENT_PREFIX) \
	    --cpu --mpi system; }

test-current: petsc-current
	. $(CURRENT_PREFIX)/env.sh && $(PY) -c 'import petsc4py; print("PETSc", petsc4py.__version__)'
	. $(CURRENT_PREFIX)/env.sh && $(PY) -m pytest -q -p no:cacheprovider $(TESTS_CURRENT)
	. $(CURRENT_PREFIX)/env.sh && $(MPIRUN) $(PY) -m mpi4py -m pytest -q -p no:cacheprovider \
	  $(TESTS_CURRENT2)

bench: install
	$(PY) runs/bench.py $(BENCH_ARGS)

report: install
	$(PY) runs/report.py $(REPORT_ARGS)

stability: install
	$(PY) runs/stability.py $(STABILITY_ARGS)

validate: install
	$(PY) runs/validate.py $(VALIDATE_ARGS)
	$(PY) runs/validate_block.py
	$(PY) runs/validate_incline.py
	$(PY) runs/validate_two_bodies.py

clean:
	rm -rf runs/out .pytest_cache

# GPU back end (README "GPU"): a CUDA PETSc + mpi4py + petsc4py from PyPI's source
# distributions; the fetch needs the network, the build does not (runs/petsc_gpu.sh).
GPU_DIST   ?= .gpu/dist
GPU_PREFIX ?= .gpu/prefix
GPU_PYTHON ?= python3
.PHONY: petsc-gpu petsc-gpu-fetch

petsc-gpu-fetch:
	PYTHON=$(GPU_PYTHON) runs/petsc_gpu.sh fetch $(GPU_DIST)

petsc-gpu:
	PYTHON=$(GPU_PYTHON) runs/petsc_gpu.sh build $(GPU_DIST) $(GPU_PREFIX) $(GPU_ARGS)
