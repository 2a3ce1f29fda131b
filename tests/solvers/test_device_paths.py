"""The loops' device paths, checked without a GPU (issue 6, GPU back end).

With a CUDA (or Kokkos) PETSc the three loops run on the GPU by options alone
(`-vec_type cuda -mat_type aijcusparse`): their work is Vec/Mat/VecScatter calls, which PETSc
runs where the Vec lives. Two things would spoil that; both are checked here on the CPU:

(a) a host array access inside the loops (getArray, setArray, getValues, setValues, ...):
    on a GPU each one copies the vector device -> host (and back). Counted with the
    interpreter's profiler (`sys.setprofile` c_call events; `sys.monitoring` CALL events on
    Python >= 3.12) while `problem.solve()` runs, attributed to the calling function and to
    the innermost loop on the stack (FixedPoint/Uzawa/APG/SSN `.solve`); a static scan of
    the loop modules covers the array *properties* (`.array`, `.array_r`, ...), which the
    profiler cannot see. The semismooth Newton path is known to build its matrix from NumPy
    arrays on the host each Newton step: its count is reported, not asserted zero. The
    default solver (coulomb.py) touches host memory by design, but only in contact space:
    the test asserts that every host access inside its iteration is to a contact-space
    Vec or the contact rows' matrix D (and to K's contact rows with -newton_jacobian
    inplace), never to a full-size Vec or A.
(b) a Vec of another type than the DM's (a host Vec among device ones): with
    `-dm_vec_type mpi` on a one-process communicator (default there: seq), every Vec the loops
    hold has the DM's type, and the answer equals the default-type answer. On several ranks
    (where mpi is the default) the `mpi` run is compared with a one-process `seq` run.

On a GPU PETSc, `CONTACT_TEST_VEC_TYPE=cuda CONTACT_TEST_MAT_TYPE=aijcusparse` runs (a) and (b)
with the device types, and `test_no_device_host_copies_in_apg_iterations` reads PETSc's own
counts of CPU<->GPU copies in the "APG iterations" event (runs/petsc_gpu.sh measure does so).
"""
import ast
import collections
import os
import re
import sys

import pytest
from conftest import gather, only_in_parallel, paper_scene, rel_err, skip_in_parallel
from mpi4py import MPI
from petsc4py import PETSc

import contact
from contact.solvers.paper.apg import APG
from contact.solvers.coulomb import CoulombNewton
from contact.solvers.paper.fixedpoint import FixedPoint
from contact.solvers.paper.ssn import SemismoothNewton
from contact.problem import ContactProblem
from contact.solvers.paper.uzawa import Uzawa

#: petsc4py methods that read or write a Vec's/Mat's values through host memory
HOST_METHODS = frozenset({
    "getArray", "setArray", "placeArray", "resetArray", "getBuffer", "getValue", "getValues",
    "setValue", "setValues", "setValuesBlocked", "setValueLocal", "setValuesLocal",
    "setValuesBlockedLocal", "getValuesStagStencil", "setValuesStagStencil",
    "createWithArray", "createGhostWithArray",
    # Mat
    "setValuesRCV", "setValuesLocalRCV", "setValuesBlockedRCV", "setValuesBlockedLocalRCV",
    "setValuesCSR", "getValuesCSR", "getRow", "getDenseArray"})
#: petsc4py properties doing the same (invisible to the profiler: static scan only)
HOST_PROPERTIES = frozenset({"array", "array_r", "array_w", "buffer", "buffer_r", "buffer_w",
                             "__array_interface__"})
#: the loops, by the code object of their solve()
LOOPS = {FixedPoint.solve.__code__: "FixedPoint", Uzawa.solve.__code__: "Uzawa",
         APG.solve.__code__: "APG", SemismoothNewton.solve.__code__: "SSN",
         CoulombNewton.solve.__code__: "Newton"}
#: host accesses inside a loop frame that are set-up, not iteration work: the start vector
#: of the power iteration for L_A, once per problem (the estimate is cached)
SETUP_IN_LOOPS = {"subproblem.py:power_iteration"}
#: the loop modules and their functions allowed to touch host memory (set-up and output)
LOOP_MODULES = ("solvers/paper/apg.py", "solvers/paper/uzawa.py",
                "solvers/paper/fixedpoint.py", "solvers/loop.py", "fem/contactset.py",
                "solvers/paper/subproblem.py")
#: the subproblem's contact-space views for the Newton Jacobian (SSN only; the APG, Uzawa
#: and fixed-point path never calls them, which the profiler test checks)
STATIC_SETUP = {"subproblem.py:power_iteration", "subproblem.py:Subproblem.contact_arrays",
                "contactset.py:ContactSet.__init__",
                "contactset.py:ContactSet.vec", "contactset.py:ContactSet.local_array"}

VEC_TYPE = os.environ.get("CONTACT_TEST_VEC_TYPE")      # e.g. cuda (a GPU PETSc)
MAT_TYPE = os.environ.get("CONTACT_TEST_MAT_TYPE")      # e.g. aijcusparse
ON_DEVICE = VEC_TYPE is not None and VEC_TYPE not in ("seq", "mpi", "standard")


def _where(frame):
    code = frame.f_code
    name = getattr(code, "co_qualname", code.co_name)
    return f"{os.path.basename(code.co_filename)}:{name}"


class HostAccesses:
    """Counts calls of HOST_METHODS on PETSc Vecs/Mats while active:
    `counts[(loop, caller)]`, loop = innermost loop on the stack (or "outside")."""

    def __init__(self):
        self.counts = collections.Counter()
        #: (loop, caller) -> what was touched: ("vec", local size) or ("mat", handle)
        self.objects = collections.defaultdict(set)
        self._tool = None

    def _record(self, frame, obj=None):
        f, loop = frame, "outside"
        while f is not None:
            if f.f_code in LOOPS:
                loop = LOOPS[f.f_code]
                break
            f = f.f_back
        self.counts[(loop, _where(frame))] += 1
        if isinstance(obj, PETSc.Vec):
            self.objects[(loop, _where(frame))].add(("vec", obj.getLocalSize()))
        elif isinstance(obj, PETSc.Mat):
            self.objects[(loop, _where(frame))].add(("mat", obj.handle))

    @staticmethod
    def _is_host(fn, obj):
        return getattr(fn, "__name__", None) in HOST_METHODS and \
            isinstance(obj, (PETSc.Vec, PETSc.Mat))

    def _profile(self, frame, event, arg):
        if event == "c_call" and self._is_host(arg, getattr(arg, "__self__", None)):
            self._record(frame, arg.__self__)

    def _call(self, code, offset, fn, arg0):
        obj = arg0 if isinstance(arg0, (PETSc.Vec, PETSc.Mat)) else getattr(fn, "__self__", None)
        if self._is_host(fn, obj):
            self._record(sys._getframe(1), obj)

    def __enter__(self):
        mon = getattr(sys, "monitoring", None)
        if mon is not None:                    # Python >= 3.12: every callable's calls
            for tool in (5, 4, 3, mon.PROFILER_ID):
                try:
                    mon.use_tool_id(tool, "contact-host-accesses")
                except ValueError:
                    continue
                self._tool = tool
                mon.register_callback(tool, mon.events.CALL, self._call)
                mon.set_events(tool, mon.events.CALL)
                return self
        sys.setprofile(self._profile)          # c_call: builtin (non-binding Cython) methods
        return self

    def __exit__(self, *exc):
        if self._tool is not None:
            mon = sys.monitoring
            mon.set_events(self._tool, 0)
            mon.register_callback(self._tool, mon.events.CALL, None)
            mon.free_tool_id(self._tool)
        else:
            sys.setprofile(None)
        return False

    def inside(self, loops=("FixedPoint", "Uzawa", "APG", "SSN")):
        return {k: n for k, n in self.counts.items() if k[0] in loops}


def _probe(v):
    v.getArray(readonly=True)


def _profiler_sees_petsc4py():
    v = PETSc.Vec().createSeq(2, comm=PETSc.COMM_SELF)
    with HostAccesses() as h:
        _probe(v)
    v.destroy()
    return sum(h.counts.values()) == 1


def _set_types(vec_type, mat_type=None):
    o = PETSc.Options()
    if vec_type:
        o.setValue("dm_vec_type", vec_type)
    if mat_type:
        o.setValue("dm_mat_type", mat_type)


def _friction_scene(**solver):
    """The paper's beam at Nd = 1 (F = 0.3: fixed point + Uzawa + APG with the prox)."""
    return paper_scene(nd=1, uzawa_r=1e6, **solver)


def _report(title, counts):
    lines = [f"{title}:"] + [f"  {n:6d}  {loop:10s} {where}"
                             for (loop, where), n in sorted(counts.items())]
    if MPI.COMM_WORLD.rank == 0:
        print("\n" + "\n".join(lines))


# -- (a) no host array access inside the loops ---------------------------------------------

def test_profiler_counts_host_accesses():
    """The counter itself: a getArray in a known frame is seen once (else the test below
    would pass vacuously)."""
    if not _profiler_sees_petsc4py():
        pytest.skip(f"this Python ({sys.version.split()[0]}) cannot profile petsc4py "
                    f"{__import__('petsc4py').__version__}'s calls (Cython binding "
                    f"functions raise no c_call event before Python 3.12); the static scan "
                    f"still runs")
    with HostAccesses() as h:
        _probe(PETSc.Vec().createSeq(2, comm=PETSc.COMM_SELF))
    assert dict(h.counts) == {("outside", "test_device_paths.py:_probe"): 1}


@pytest.mark.parametrize("variant", [
    {},                                                  # the paper's (faithful) iteration
    {"apg_restart": "gradient"},
    {"apg_restart": "function", "apg_metric": "diagonal"},
    {"apg_step": "backtracking"},
    {"fp_warm_start": "xl", "uzawa_inexact": "0.1", "fp_inexact": "0.1"},
], ids=["faithful", "restart-gradient", "restart-function-diagonal", "backtracking",
        "warm-inexact"])
def test_no_host_access_inside_the_loops(comm, variant):
    if not _profiler_sees_petsc4py():
        pytest.skip("the profiler cannot see petsc4py's calls here (see the probe test)")
    _set_types(VEC_TYPE, MAT_TYPE)
    for k, v in variant.items():
        PETSc.Options().setValue(k, v)
    pr = ContactProblem(_friction_scene(), comm)
    with HostAccesses() as h:
        pr.solve()
    assert pr.mode == "coulomb" and pr.fp.iterations > 1 and pr.apg is not None
    inside = h.inside()
    _report(f"host accesses during solve() [{variant or 'faithful'}], "
            f"{pr.apg.total_iterations} APG iterations", h.counts)
    iteration_work = {k: n for k, n in inside.items() if k[1] not in SETUP_IN_LOOPS}
    assert iteration_work == {}, f"host array accesses inside the loops: {iteration_work}"
    # the set-up inside the first APG call happens once, not per iteration or per call
    assert sum(inside.values()) <= 1
    # and the counter did see the host work outside the loops (the residual check)
    assert any(k[0] == "outside" for k in h.counts)


def _functions(tree):
    """(qualified name, node) of every function of a module."""
    out = []

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                out.append((prefix + child.name, child))
                visit(child, prefix + child.name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, prefix + child.name + ".")
    visit(tree, "")
    return out


def test_loop_modules_use_no_host_arrays_outside_setup():
    """Static scan: no host-array method or property in the loop modules' functions, except
    the set-up ones listed in STATIC_SETUP (the profiler does not see properties)."""
    pkg = os.path.dirname(contact.__file__)
    found, setup_seen = [], set()
    for mod in LOOP_MODULES:
        with open(os.path.join(pkg, mod)) as f:
            tree = ast.parse(f.read())
        for name, fn in _functions(tree):
            where = f"{os.path.basename(mod)}:{name}"
            direct = [n for n in ast.walk(fn) if isinstance(n, ast.Attribute)
                      and n.attr in HOST_METHODS | HOST_PROPERTIES]
            if direct and where in STATIC_SETUP:
                setup_seen.add(where)
            elif direct:
                found += [f"{where} line {n.lineno}: .{n.attr}" for n in direct]
    assert found == []
    assert setup_seen == STATIC_SETUP          # the allowlist is not stale


def test_ssn_host_work_per_newton_step(comm):
    """Report (not assert zero): the semismooth Newton path builds its matrix and right-hand
    side from host arrays each Newton step. This is also the counter's positive control."""
    if not _profiler_sees_petsc4py():
        pytest.skip("the profiler cannot see petsc4py's calls here (see the probe test)")
    _set_types(VEC_TYPE, MAT_TYPE)
    PETSc.Options().setValue("solver_mode", "fast")
    pr = ContactProblem(paper_scene(nd=2, uzawa_r=1e6), comm)
    with HostAccesses() as h:
        pr.solve()
    assert pr.inner.name == "ssn"
    ssn = h.inside(("SSN",))
    steps = pr.inner.total_iterations
    per_step = collections.Counter()
    for (_, where), n in ssn.items():
        per_step[where] += n
    _report(f"SSN host accesses: {sum(ssn.values())} in {steps} Newton steps "
            f"({sum(ssn.values()) / steps:.1f} per step; per rank)",
            {("SSN", w): n for w, n in per_step.items()})
    assert sum(ssn.values()) >= steps                 # the known host work is seen
    # nothing of the fixed point and Uzawa loops themselves
    assert {k: n for k, n in h.inside(("FixedPoint", "Uzawa")).items()} == {}


@pytest.mark.parametrize("storage", ["separate", "inplace"])
def test_newton_host_work_is_the_contact_rows(comm, storage):
    """The default solver (contact/solvers/coulomb.py): inside its iteration a host array is only
    ever one of contact space (a Vec of at most 3 x the rank's contact nodes: the contact
    rows' values, kilobytes), and a Mat's values only D's (K - A in the contact rows) with
    -newton_jacobian separate (the GPU's), or also K's own contact rows in place: never a
    full-size Vec or A. (-vec_type cuda then moves only those between host and device.)"""
    if not _profiler_sees_petsc4py():
        pytest.skip("the profiler cannot see petsc4py's calls here (see the probe test)")
    _set_types(VEC_TYPE, MAT_TYPE)
    PETSc.Options().setValue("newton_jacobian", storage)
    try:
        pr = ContactProblem(paper_scene(nd=4, mode="newton", c2f_levels=0), comm)
        with HostAccesses() as h:
            pr.solve()
    finally:
        for k in ("newton_jacobian", "dm_vec_type", "dm_mat_type"):
            PETSc.Options().delValue(k)
    n = pr.inner
    assert n.name == "newton" and n.jac.separate == (storage == "separate")
    inside = {k: h.objects[k] for k in h.inside(("Newton",))}
    _report(f"Newton host accesses ({storage}, {n.iterations} steps)",
            {k: h.counts[k] for k in inside})
    touched = set().union(*inside.values()) if inside else set()
    vecs = {s for kind, s in touched if kind == "vec"}
    mats = {s for kind, s in touched if kind == "mat"}
    m = n.cs.local_size
    assert max(vecs, default=0) <= 3 * m, (vecs, m)
    allowed = ({n.jac.D.handle} if n.jac.D is not None else set()) | (
        set() if storage == "separate" else {n.jac.K.handle})        # (inplace: K is A)
    assert mats <= allowed, (mats, allowed)
    if storage == "separate":
        assert n.jac.K.handle != pr.disc.A.handle and pr.disc.A.handle not in mats
    assert MPI.COMM_WORLD.allreduce(sum(h.counts[k] for k in inside)) > 0   # seen at all


# -- (b) every Vec of the loops has the DM's type ---------------------------------------------

def _loop_vecs(pr):
    """name -> Vec for every Vec held by the problem, its solution, its contact set and its
    loops."""
    out = {}
    for owner_name in ("problem", "solution", "cs", "fp", "uzawa", "sub", "inner"):
        owner = pr if owner_name == "problem" else pr.uzawa.sub if owner_name == "sub" \
            else getattr(pr, owner_name)
        if owner is None:
            continue
        for attr, val in vars(owner).items():
            items = val if isinstance(val, (list, tuple)) else [val]
            for i, v in enumerate(items):
                if isinstance(v, PETSc.Vec) and v.handle:
                    key = f"{owner_name}.{attr}" + (f"[{i}]" if len(items) > 1 else "")
                    out[key] = v
    return out


def _dm_vec_type(pr):
    g = pr.dm.createGlobalVec()
    t = g.getType()
    g.destroy()
    return t


VARIANTS_B = [{}, {"apg_restart": "function", "apg_metric": "diagonal"},
              {"solver_mode": "fast"}]


def _solve_typed(comm, variant, vec_type, mat_type):
    _set_types(vec_type, mat_type)
    for k, v in variant.items():
        PETSc.Options().setValue(k, v)
    pr = ContactProblem(_friction_scene(), comm).solve()
    for k in ("dm_vec_type", "dm_mat_type", *variant):
        PETSc.Options().delValue(k)
    return pr


def _check_types(comm, variant):
    vec_type, mat_type = (VEC_TYPE, MAT_TYPE) if VEC_TYPE else ("mpi", None)
    ref = _solve_typed(comm, variant, None, None)
    pr = _solve_typed(comm, variant, vec_type, mat_type)
    dm_type = _dm_vec_type(pr)
    if vec_type == "mpi":
        assert dm_type == "mpi"
    if comm.getSize() == 1 and not VEC_TYPE:
        assert _dm_vec_type(ref) == "seq" != dm_type          # a non-default type indeed
    vecs = _loop_vecs(pr)
    assert {"problem.x", "solution.l", "solution.g", "cs.w", "uzawa.l_new"} <= set(vecs)
    if pr.apg is not None:
        assert {"inner.y", "inner.grad", "inner.thr", "sub._s"} <= set(vecs)
    wrong = {k: v.getType() for k, v in vecs.items() if v.getType() != dm_type}
    assert wrong == {}, f"Vecs not of the DM's type {dm_type}: {wrong}"
    if mat_type:
        assert mat_type in pr.A.getType()
    if ON_DEVICE:        # other summation orders: the loops may stop an iteration apart
        assert rel_err(gather(pr)[1], gather(ref)[1]) < 1e-5
    else:                # the same operations in the same order
        assert rel_err(gather(pr)[1], gather(ref)[1]) < 1e-12
        assert pr.fp.iterations == ref.fp.iterations
    if comm.getSize() > 1 and not VEC_TYPE:
        # on several ranks `mpi` is already the default type, so `ref` above is the same
        # run: compare the explicitly typed run with a one-process run of the standard
        # (seq) type instead. Other partition, other summation order: equal to rounding
        # (the loops stop on a relative change, so they may stop an iteration apart).
        ser = _solve_typed(PETSc.COMM_SELF, variant, None, None)
        assert _dm_vec_type(ref) == "mpi" and _dm_vec_type(ser) == "seq" != dm_type
        assert ser.converged and pr.converged
        assert rel_err(gather(pr)[1], gather(ser)[1]) < 1e-6
    return pr


@pytest.mark.parametrize("variant", VARIANTS_B, ids=["faithful", "restart-function-diagonal",
                                                      "fast"])
def test_loop_vecs_have_the_dm_type_on_one_process(variant):
    """On COMM_SELF (every rank, when run under mpirun)."""
    _check_types(PETSc.COMM_SELF, variant)


@only_in_parallel
@pytest.mark.parametrize("variant", VARIANTS_B, ids=["faithful", "restart-function-diagonal",
                                                      "fast"])
def test_loop_vecs_have_the_dm_type_on_all_ranks(variant):
    _check_types(PETSc.COMM_WORLD, variant)


# -- on a GPU PETSc: PETSc's own count of CPU<->GPU copies ----------------------------------

@pytest.mark.skipif(not ON_DEVICE, reason="needs a GPU PETSc and CONTACT_TEST_VEC_TYPE=cuda "
                                          "(runs/petsc_gpu.sh measure)")
@skip_in_parallel           # with an MPI that is not GPU-aware, scatters between ranks copy
def test_no_device_host_copies_in_apg_iterations(tmp_path):
    """-log_view's CpuToGpu / GpuToCpu columns of the "APG iterations" event: nothing larger
    than a scalar (the norms and dots the loop tests on) crosses between host and device."""
    _set_types(VEC_TYPE, MAT_TYPE)
    PETSc.Log.begin()
    pr = ContactProblem(paper_scene(nd=2, uzawa_r=1e6), PETSc.COMM_SELF).solve()
    path = str(tmp_path / "log.txt")
    viewer = PETSc.Viewer().createASCII(path, comm=PETSc.COMM_SELF)
    PETSc.Log.view(viewer)
    viewer.destroy()
    text = open(path).read()
    m = re.search(r"^APG iterations\s+(\d+)\s(.*)$", text, re.M)
    assert m, "no APG iterations event in -log_view"
    cct, csz, gct, gsz = (float(c) for c in m.group(2).split()[-5:-1])
    print(f"\nAPG iterations ({pr.apg.total_iterations}): CpuToGpu {cct:.0f} copies, "
          f"{csz:.3g} MB; GpuToCpu {gct:.0f} copies, {gsz:.3g} MB")
    assert csz * 1e6 <= 8.1 * cct + 1.0         # sizes are printed in MB with 3 digits
    assert gsz * 1e6 <= 8.1 * gct + 1.0
