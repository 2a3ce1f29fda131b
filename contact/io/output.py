"""Results on disk: solution.h5, solution.xdmf (ParaView), summary.json, figures (PNG).

solution.h5 is written by all ranks together (PETSc's HDF5 viewer, MPI-IO), each rank its
own piece of every dataset, nothing gathered: nodes, cells, contact nodes and contact
faces are put in a canonical order that does not depend on the partition (nodes and
contact nodes sorted by (z, y, x), cells and faces by their sorted node numbers:
layout.Layout, a parallel sample sort, contact/mesh/canonical.py) and moved there by
VecScatters, so 1 and 2 ranks write the same datasets. The datasets are listed once, in
`BODY`, `CONTACT` (and `MESH`): the HDF5 writer, the XDMF description and the README
follow them.
A quasi-static run (load steps) also keeps every increment's fields under /steps/NNNN/
and the XDMF plays them as a temporal collection.

Files are written under temporary names and renamed together when all are complete
(summary.json last), so a failed or interrupted run leaves no result file.
The canonical orders and the data gathered on rank 0 (tests, scripts, the figures'
figure_data) are in layout.py.
"""
import ctypes
import json
import os
from typing import NamedTuple

import numpy as np
from petsc4py import PETSc

from contact import options
from contact.analysis import stress
from contact.io.layout import Layout, figure_data, gather_state

INT = np.dtype(PETSc.IntType)          # integer datasets: PETSc's IS type (int32 here)


class Field(NamedTuple):
    name: str          # the XDMF attribute's name (what ParaView shows)
    path: str          # the dataset, under the state's prefix ('' or /steps/NNNN)
    comps: int         # 1 scalar, 3 vector, 6 symmetric tensor (stress.COMPONENTS)
    center: str        # Node or Cell
    kind: str = "f"    # f: float64, i: INT
    help: str = ""


#: the body's fields (nodes and cells of /mesh)
BODY = (Field("displacement", "fields/displacement", 3, "Node", help="u (x, y, z)"),
        Field("displacement_magnitude", "fields/displacement_magnitude", 1, "Node",
              help="|u|"),
        Field("stress", "fields/stress", 6, "Node", help="Cauchy stress, volume-weighted "
              "average of the adjacent cells' means; xx, yy, zz, xy, yz, xz"),
        Field("von_mises", "fields/von_mises", 1, "Node", help="von Mises of `stress`"),
        Field("cell_stress", "cells/stress", 6, "Cell", help="Cauchy stress, cell mean of "
              "the 2x2x2 Gauss values; xx, yy, zz, xy, yz, xz"),
        Field("cell_von_mises", "cells/von_mises", 1, "Cell",
              help="von Mises of `cell_stress`"),
        Field("cell_pressure", "cells/pressure", 1, "Cell",
              help="p = -tr(`cell_stress`) / 3: bbar's cell pressure -kappa div_e u, q2p1's "
                   "projected pressure's mean over the cell"),
        Field("cell_error_indicator", "cells/error_indicator", 1, "Cell",
              help="||u_h - P u_2h||_a on the cell: where the last refinement changed the "
                   "solution, i.e. where the error lives (contact/analysis/estimate.py); NaN "
                   "where there is no coarse level (one mesh level)"),
        Field("body", "cells/body", 1, "Cell", help="the cell's body: its place in the "
              "scene's bodies: (0 in a one-body scene; float64 as status)"))
#: the contact nodes' fields (stress.contact_state)
CONTACT = (Field("pressure", "contact/pressure", 1, "Node",
                 help="g = -sigma_nu >= 0, the loops' multiplier l"),
           Field("slip", "contact/slip", 1, "Node", help="|u_tau| (of the last increment)"),
           Field("status", "contact/status", 1, "Node",
                 help="0 separated, 1 stick, 2 slip (float64: PETSc's HDF5 viewer writes "
                 "integers as 2-D datasets only)"),
           Field("traction", "contact/traction", 3, "Node",
                 help="R / w (x, y, z): force per area of the foundation on the body"),
           Field("normal_traction", "contact/normal_traction", 1, "Node",
                 help="R . n / w: the pressure from the reaction (= pressure to the "
                 "loops' tolerance)"),
           Field("friction", "contact/friction", 1, "Node",
                 help="|sigma_tau|: friction force per area"),
           Field("friction_use", "contact/friction_use", 1, "Node",
                 help="|sigma_tau| / (F g) in contact (1: at the Coulomb bound), else 0"),
           Field("normal_displacement", "contact/normal_displacement", 1, "Node",
                 help="-u_nu = u . n (> 0: away from the foundation)"),
           Field("tangential_displacement", "contact/tangential_displacement", 1, "Node",
                 help="|u_tau| of the whole displacement"))
#: the geometry (written once; not per step)
MESH = (Field("coordinates", "/mesh/coordinates", 3, "Node", help="nodes, sorted by (z, y, x)"),
        Field("topology", "/mesh/topology", 8, "Cell", "i", help="hexahedra, VTK order"),
        Field("coordinates", "/contact/coordinates", 3, "Node",
              help="contact nodes (not clamped), sorted by (z, y, x)"),
        Field("topology", "/contact/topology", 4, "Cell", "i",
              help="contact faces whose 4 corners are contact nodes: rows of "
              "/contact/coordinates"),
        Field("load_factor", "/steps/load_factor", 1, "", help="quasi-static runs: t of "
              "each increment; /steps/NNNN/ holds its fields (NNNN = 0001 .. N-1; the "
              "last increment is the top-level fields)"))

FORMATS = ("h5", "xdmf", "json", "png")

#: the number of rows of each dataset: nodes, cells, contact nodes, contact faces, steps
_ROWS = {"/mesh/coordinates": "n", "/mesh/topology": "nc", "/contact/coordinates": "m",
         "/contact/topology": "mf", "/steps/load_factor": "N"}


def dataset_table():
    """The README's table of solution.h5 (tests/io/test_output_files.py holds it equal)."""
    rows = ["| dataset | shape, type | meaning |", "|---|---|---|"]
    for f in MESH + BODY + CONTACT:
        path = f.path if f.path.startswith("/") else "/" + f.path
        n = _ROWS.get(path) or ("m" if f in CONTACT else "n" if f.center == "Node" else "nc")
        kind = f"int{8 * INT.itemsize}" if f.kind == "i" else "float64"
        text = f.help.replace("|", "\\|")
        rows.append(f"| `{path}` | {n}{f' x {f.comps}' if f.comps > 1 else ''}, {kind} "
                    f"| {text} |")
    return "\n".join(rows)


def parse_formats(text):
    """-output_formats h5,xdmf,json[,png] ('none': no file): a tuple of FORMATS."""
    kinds = tuple(k.strip() for k in text.split(",") if k.strip())
    if kinds == ("none",):
        return ()
    bad = [k for k in kinds if k not in FORMATS]
    if bad:
        raise ValueError(f"-output_formats: unknown format {bad[0]!r} (choose among "
                         f"{', '.join(FORMATS)}, or none)")
    if "xdmf" in kinds and "h5" not in kinds:
        raise ValueError("-output_formats: xdmf describes the h5 file; ask for h5 too")
    return kinds


# -- gathered on rank 0 (tests, scripts) -----------------------------------------------------
def gather_contact(problem, x=None):
    """On rank 0: the contact fields of stress.contact_state (coordinates, pressure, slip,
    status, traction, ...) in canonical order; slip and status of x (default the last
    load increment's, else the solution's)."""
    comm = problem.comm.tompi4py()
    cs = problem.cs
    if cs is None or cs.size == 0:
        if comm.rank:
            return None
        out = {f.name: np.zeros((0, 3) if f.comps == 3 else 0,
                                dtype=INT if f.kind == "i" else float) for f in CONTACT}
        return dict(out, coordinates=np.zeros((0, 3)), w=np.zeros(0), F=np.zeros(0))
    return gather_state(comm, stress.contact_state(problem, slip=x))


# -- the states written: the solution, and each load increment of a quasi-static run ------
def requested_formats():
    """-output_formats, parsed (the one reading of it: the command line and the increments'
    recorder)."""
    return parse_formats(options.get("output_formats"))


def increment_recorder():
    """The monitor handed to driver.solve: (record, increments), record(sol, t, factors, v,
    b, gap) keeping each increment's contact fields and resultants (contact-sized), and its
    displacement v (u - u_D, a copy: one Vec per increment) when solution.h5 is asked for,
    in the list increments; record is None when -output_formats asks for no file."""
    formats = requested_formats()
    increments = []
    if not formats:
        return None, increments
    keep_body = "h5" in formats

    def record(sol, t, factors, v, b, gap):
        """After increment t: sol.x = its du, v = u - u_D; b, gap its load and gap."""
        st = stress.contact_state(sol, sol.x, b, gap, u=v, slip=sol.x)
        increments.append({
            "t": t, "contact": st, "factors": list(factors),
            "x": v.copy() if keep_body else None,
            "resultant": stress.resultants(sol.comm.tompi4py(), st, stress.normals(sol)),
            "pairs": stress.by_pair(sol.comm.tompi4py(), sol.disc, st)})
    return record, increments


def _prescribed_factor(problem, factors):
    """u_D(t) = f u_D when the prescribed displacements all share one load group (factor
    f); None when several groups prescribe displacements (u_D(t) not kept)."""
    if problem.u_D is None:
        return 0.0
    moving = {n for n, p in problem.scene["boundary"].items() if p["type"] == "dirichlet"
              and np.any(np.asarray(p.get("displacement", [0, 0, 0]), dtype=float) != 0)}
    groups = [i for i, (_, names, _) in enumerate(problem.load_groups) if moving & set(names)]
    return factors[groups[0]] if len(groups) == 1 else None


def states(problem):
    """[(prefix, t, body u (x, y, z Vec) or None, contact state or None)]: the load
    increments before the last (prefix /steps/NNNN) and the solution (prefix '')."""
    out = []
    steps = getattr(problem, "increments", None) or []
    cs_ok = problem.cs is not None and problem.cs.size > 0
    for k, s in enumerate(steps[:-1], start=1):
        u = None
        f = _prescribed_factor(problem, s["factors"]) if s["x"] is not None else None
        if f is not None:
            u = s["x"].copy()
            if f:
                u.axpy(f, problem.u_D)
            u = problem.disc.to_xyz(u)
        out.append((f"/steps/{k:04d}", s["t"], u, s["contact"] if cs_ok else None))
    final = stress.final(problem)
    out.append(("", 1.0 if steps else None, None, final["contact"]))
    return out


# -- HDF5, collective ------------------------------------------------------------------------
_LIB = None


def _group(viewer, name):
    """PetscViewerHDF5PushGroup(name) / PopGroup (None) (not in petsc4py 3.18)."""
    global _LIB
    if _LIB is None:
        _LIB = ctypes.CDLL(PETSc.__file__)
    h = ctypes.c_void_p(viewer.handle)
    ierr = _LIB.PetscViewerHDF5PopGroup(h) if name is None else \
        _LIB.PetscViewerHDF5PushGroup(h, name.encode())
    if ierr:
        raise PETSc.Error(ierr)


def _view(viewer, path, obj):
    """Write the Vec or IS `obj` as the dataset `path` (absolute), then destroy it."""
    group, _, name = path.rpartition("/")
    obj.setName(name)
    _group(viewer, group or "/")
    obj.view(viewer)
    _group(viewer, None)
    obj.destroy()


def _view_int(viewer, path, values, comm, bs=1):
    iset = PETSc.IS().createGeneral(np.ascontiguousarray(values, dtype=INT).ravel(), comm=comm)
    if bs > 1:
        iset.setBlockSize(bs)
    _view(viewer, path, iset)


def _body_values(body, u, indicator=None, body_of=None):
    """Owned node / local cell arrays of the BODY fields (indicator: the local cells'
    error indicator, or None: NaN; body_of: each local cell's body, None: one body)."""
    un = u.getArray(readonly=True).reshape(-1, 3)
    nc = body["cell"].shape[0]
    return {"displacement": un, "displacement_magnitude": np.linalg.norm(un, axis=1),
            "stress": body["nodal"], "von_mises": body["nodal_von_mises"],
            "cell_stress": body["cell"], "cell_von_mises": body["cell_von_mises"],
            "cell_pressure": -body["cell"][:, :3].sum(axis=1) / 3.0,
            "cell_error_indicator": np.full(nc, np.nan) if indicator is None else indicator,
            "body": np.zeros(nc) if body_of is None else body_of.astype(float)}


def write_hdf5(path, problem, layout, written):
    """solution.h5 at `path` from all ranks: the geometry once, then the fields of each
    state of `written` (from `states`; body None: that step's body fields are not kept)."""
    comm = problem.comm
    viewer = PETSc.Viewer().createHDF5(path, "w", comm=comm)
    try:
        L = layout
        _view(viewer, "/mesh/coordinates", L.nodes.scatter(problem.coordinates, 3))
        _view_int(viewer, "/mesh/topology", L.cells.payload[0], comm, 8)
        if L.contact is not None:
            cs = problem.cs
            _view(viewer, "/contact/coordinates",
                  L.contact.scatter(L.contact.source_vec(cs.coordinates, 3), 3))
            _view_int(viewer, "/contact/topology", L.faces.payload[0], comm, 4)
        else:                       # no contact node: empty datasets, as before
            empty = PETSc.Vec().createMPI((0, 0), bsize=3, comm=comm)
            _view(viewer, "/contact/coordinates", empty)
        if len(written) > 1:
            t = PETSc.Vec().createMPI((len(written) if comm.rank == 0 else 0,
                                       PETSc.DECIDE), comm=comm)
            if comm.rank == 0:
                t.setArray(np.array([s[1] for s in written], dtype=float))
            _view(viewer, "/steps/load_factor", t)
        for prefix, _, u, contact in written:
            final = prefix == ""
            if final:
                body, u = stress.final(problem)["body"], problem.displacement()
            elif u is not None:
                body = stress.body_stress(problem, u)
            if u is not None:
                ind = problem.error_indicator[0] if final and problem.error_indicator \
                    is not None else None
                vals = _body_values(body, u, ind, problem.disc.body_of)
                for f in BODY:
                    order = L.nodes if f.center == "Node" else L.cells
                    src = u if f.name == "displacement" else order.source_vec(vals[f.name],
                                                                               f.comps)
                    _view(viewer, f"{prefix}/{f.path}", order.scatter(src, f.comps))
                    if src is not u:
                        src.destroy()
                if not final:
                    u.destroy()
            _write_contact(viewer, prefix, L, contact, comm)
    finally:
        viewer.destroy()


def _write_contact(viewer, prefix, L, state, comm):
    for f in CONTACT:
        path = f"{prefix}/{f.path}"
        if L.contact is None:
            if prefix == "":
                _view(viewer, path, PETSc.Vec().createMPI((0, 0), bsize=f.comps, comm=comm))
            continue
        src = L.contact.source_vec(state[f.name], f.comps)
        _view(viewer, path, L.contact.scatter(src, f.comps))
        src.destroy()


# -- XDMF ------------------------------------------------------------------------------------
def _item(h5name, path, dims, kind):
    number = f'NumberType="Int" Precision="{INT.itemsize}"' if kind == "i" else \
        'NumberType="Float" Precision="8"'
    d = " ".join(str(x) for x in dims)
    return f'<DataItem Dimensions="{d}" {number} Format="HDF">{h5name}:{path}</DataItem>'


_ATTR = {1: "Scalar", 3: "Vector", 6: "Tensor6"}


def _grid(h5name, name, prefix, t, sizes, kind, body_fields):
    """One Uniform grid: the body (hexahedra) or the contact face (quadrilaterals, or
    points when no face has 4 contact nodes)."""
    n, ne = (sizes["nodes"], sizes["cells"]) if kind == "body" else \
        (sizes["contact"], sizes["faces"])
    pad = " " * 6
    lines = [f'<Grid Name="{name}" GridType="Uniform">']
    if t is not None:
        lines.append(f'  <Time Value="{t:.10g}"/>')
    if kind == "body":
        lines += [f'  <Topology TopologyType="Hexahedron" NumberOfElements="{ne}" '
                  f'NodesPerElement="8">',
                  "    " + _item(h5name, "/mesh/topology", (ne, 8), "i"), "  </Topology>",
                  '  <Geometry GeometryType="XYZ">',
                  "    " + _item(h5name, "/mesh/coordinates", (n, 3), "f"), "  </Geometry>"]
        fields = BODY if body_fields else ()
    else:
        if ne:
            lines += [f'  <Topology TopologyType="Quadrilateral" NumberOfElements="{ne}" '
                      f'NodesPerElement="4">',
                      "    " + _item(h5name, "/contact/topology", (ne, 4), "i"),
                      "  </Topology>"]
        else:
            lines.append(f'  <Topology TopologyType="Polyvertex" NumberOfElements="{n}" '
                         f'NodesPerElement="1"/>')
        lines += ['  <Geometry GeometryType="XYZ">',
                  "    " + _item(h5name, "/contact/coordinates", (n, 3), "f"),
                  "  </Geometry>"]
        fields = CONTACT
    for f in fields:
        count = n if f.center == "Node" else sizes["cells"]
        dims = (count,) if f.comps == 1 else (count, f.comps)
        lines += [f'  <Attribute Name="{f.name}" AttributeType="{_ATTR[f.comps]}" '
                  f'Center="{f.center}">',
                  "    " + _item(h5name, f"{prefix}/{f.path}", dims, f.kind),
                  "  </Attribute>"]
    lines.append("</Grid>")
    return "\n".join(pad + ln for ln in lines)


def xdmf_text(h5name, sizes, written):
    """solution.xdmf: the grids `body` and (with contact nodes) `contact`; with load
    increments each is a temporal collection, one grid per increment (Time = t)."""
    out = []
    kinds = ["body"] + (["contact"] if sizes["contact"] else [])
    for kind in kinds:
        if len(written) == 1:
            out.append(_grid(h5name, kind, "", None, sizes, kind, True)[2:])
            continue
        out.append(f'    <Grid Name="{kind}" GridType="Collection" CollectionType="Temporal">')
        for prefix, t, u, _ in written:
            out.append(_grid(h5name, kind, prefix, t, sizes, kind,
                             prefix == "" or u is not None))
        out.append("    </Grid>")
    return ('<?xml version="1.0" ?>\n<Xdmf Version="3.0">\n  <Domain>\n'
            + "\n".join(out) + "\n  </Domain>\n</Xdmf>\n")


def _write_text(path, text):
    with open(path, "w") as f:
        f.write(text)


# -- staging, directories ---------------------------------------------------------------------
class Staged:
    """Files written under temporary names (`tmp(path)`, or `with Staged(*paths) as tmp:
    tmp[path]`), renamed all together by `commit` (in the order registered: summary.json
    last) or removed by `abort`, on any error or interrupt: a directory never holds a
    half-written file or a mixed set. `tag` makes the names the same on every rank (a
    file all ranks write)."""

    def __init__(self, *paths, tag=None):
        self.suffix = f".tmp{tag if tag is not None else os.getpid()}"
        self.tmp = {}
        for p in paths:
            self.path(p)

    def path(self, p):
        """The temporary name of `p` (registered for the rename)."""
        return self.tmp.setdefault(p, p + self.suffix)

    def commit(self):
        for p, t in self.tmp.items():
            os.replace(t, p)

    def abort(self):
        for t in self.tmp.values():
            if os.path.exists(t):
                os.remove(t)

    def __enter__(self):
        return self.tmp

    def __exit__(self, kind, value, tb):
        if kind is None:
            self.commit()
        else:
            self.abort()
        return False


def prepare_dir(comm, outdir):
    """Create the output directory on rank 0; one clear error for every rank if it fails."""
    err = None
    if comm.rank == 0:
        try:
            os.makedirs(outdir, exist_ok=True)
            probe = os.path.join(outdir, f".write_test{os.getpid()}")
            with open(probe, "w"):
                pass
            os.remove(probe)
        except OSError as e:
            err = f"cannot write to output directory {outdir}: {e.strerror}"
    err = comm.bcast(err, root=0)
    if err:
        raise OSError(err)


# -- all files --------------------------------------------------------------------------------
NAMES = {"h5": "solution.h5", "xdmf": "solution.xdmf", "json": "summary.json"}


def write_results(problem, outdir, summary, formats=FORMATS):
    """The files of `formats` (solution.h5, solution.xdmf, summary.json, figures/*.png);
    collective: solution.h5 from all ranks, the others on rank 0; nothing is computed or
    gathered for files not asked for. All or none: temporary names, renamed at the end."""
    comm = problem.comm.tompi4py()
    if not formats:
        return
    stage = Staged(tag=comm.bcast(os.getpid(), root=0))
    paths = {k: os.path.join(outdir, NAMES[k]) for k in ("h5", "xdmf") if k in formats}
    err = None
    try:
        try:
            written = states(problem) if "h5" in formats else None
            if "h5" in formats:
                layout = Layout(problem)
                sizes = layout.sizes
                write_hdf5(stage.path(paths["h5"]), problem, layout, written)
                layout.destroy()
            data = figure_data(problem, summary) if "png" in formats else None
            if comm.rank == 0:
                if "xdmf" in paths:
                    _write_text(stage.path(paths["xdmf"]),
                                xdmf_text(NAMES["h5"], sizes, written))
                if "png" in formats:
                    from contact.io import figures  # matplotlib only when figures are asked
                    figures.write_all(data, outdir, stage.path)
                if "json" in formats:
                    _write_text(stage.path(os.path.join(outdir, NAMES["json"])),
                                json.dumps(summary, indent=2) + "\n")
        except (OSError, PETSc.Error) as e:
            err = f"cannot write results to {outdir}: {getattr(e, 'strerror', None) or e}"
        errs = [e for e in comm.allgather(err) if e]
        if comm.rank == 0:
            if errs:
                stage.abort()
            else:
                stage.commit()
    except BaseException:
        if comm.rank == 0:
            stage.abort()
        raise
    if errs:
        raise OSError(errs[0])
