"""Results on disk: solution.h5, solution.xdmf (ParaView), summary.json.

Nodes are written in a canonical order that does not depend on the partition: sorted
lexicographically by (z, y, x) coordinates. Data are gathered to rank 0 once, after the
solve; the files are written under temporary names and renamed together when all are
complete (summary.json last), so a failed or interrupted run leaves no half-written file.
"""
import json
import os

import numpy as np

from . import residuals as res

#: PETSc hexahedron vertex order -> VTK/XDMF hexahedron order
PETSC_TO_VTK_HEX = np.array([0, 3, 2, 1, 4, 5, 6, 7])


def _gatherv(comm, a):
    parts = comm.gather(np.ascontiguousarray(a), root=0)
    return np.concatenate(parts) if comm.rank == 0 else None


def canonical_order(xyz):
    """Permutation sorting points by (z, y, x)."""
    return np.lexsort((xyz[:, 0], xyz[:, 1], xyz[:, 2]))


def gather_nodes(problem, x=None):
    """On rank 0: coordinates (n,3), displacement (n,3), cells (nc,8) in canonical order."""
    comm = problem.comm.tompi4py()
    x = problem.to_xyz(x) if x is not None else problem.displacement()
    xyz = problem.coordinates.getArray(readonly=True).reshape(-1, 3)
    u = x.getArray(readonly=True).reshape(-1, 3)
    rstart = problem.coordinates.getOwnershipRange()[0] // 3
    gid = rstart + np.arange(xyz.shape[0])
    lg = problem.dm.getLGMap().getBlockIndices()              # local vertex -> global node
    cells = lg[problem.conn] if problem.conn.size else np.zeros((0, 8), dtype=int)
    XYZ, U, GID, CELLS = (_gatherv(comm, a) for a in (xyz, u, gid, cells))
    if comm.rank != 0:
        return None
    order = canonical_order(XYZ)
    canon = np.empty(GID.max() + 1, dtype=np.int64)
    canon[GID[order]] = np.arange(order.size)
    C = canon[CELLS]
    C = C[np.lexsort(np.sort(C, axis=1).T[::-1])]              # cells in a canonical order too
    return XYZ[order], U[order], C


def gather_contact(problem, x=None):
    """On rank 0: contact coordinates, pressure g = l, slip |u_tau|, status (canonical
    order): 0 open (g = 0), 1 stick, 2 slip. With load increments, slip and status are
    those of the last increment (du_tau), as the quasi-static problem defines them."""
    comm = problem.comm.tompi4py()
    cs = problem.cs
    if cs is None or cs.size == 0:
        return None if comm.rank else {k: np.zeros((0, 3) if k == "coordinates" else 0)
                                       for k in ("coordinates", "pressure", "slip", "status")}
    if x is None:
        x = problem.last_increment
    f = res.contact_fields(problem, x)
    pressure = f["l"]
    slip = np.linalg.norm(f["u"][:, :2], axis=1)
    umax = res.max_displacement(comm, x if x is not None else problem.x)
    status = np.where(pressure > 0.0, np.where(slip > 1e-6 * max(umax, 1e-300), 2, 1), 0)
    data = {k: _gatherv(comm, v) for k, v in (("coordinates", cs.coordinates),
                                              ("pressure", pressure), ("slip", slip),
                                              ("status", status.astype(np.int8)))}
    if comm.rank != 0:
        return None
    order = canonical_order(data["coordinates"])
    return {k: v[order] for k, v in data.items()}


class Staged:
    """Write a set of files under temporary names; rename them all (summary.json last)
    only when every one is complete, and remove the temporaries on any error or
    interrupt: a directory never holds a half-written file or a mixed set."""

    def __init__(self, *paths):
        self.paths = paths
        self.tmp = {p: f"{p}.tmp{os.getpid()}" for p in paths}

    def __enter__(self):
        return self.tmp

    def __exit__(self, kind, value, tb):
        if kind is None:
            for p in self.paths:
                os.replace(self.tmp[p], p)
        else:
            for t in self.tmp.values():
                if os.path.exists(t):
                    os.remove(t)
        return False


def write_hdf5(path, nodes, contact):
    import h5py
    xyz, u, cells = nodes
    with h5py.File(path, "w") as f:
        f["/mesh/coordinates"] = xyz
        f["/mesh/topology"] = cells[:, PETSC_TO_VTK_HEX].astype(np.int64)
        f["/fields/displacement"] = u
        f["/fields/displacement_magnitude"] = np.linalg.norm(u, axis=1)
        for k in ("coordinates", "pressure", "slip", "status"):
            f[f"/contact/{k}"] = contact[k]


def write_xdmf(path, h5name, n, nc, m):
    grid_contact = f"""
    <Grid Name="contact" GridType="Uniform">
      <Topology TopologyType="Polyvertex" NumberOfElements="{m}" NodesPerElement="1"/>
      <Geometry GeometryType="XYZ">
        <DataItem Dimensions="{m} 3" NumberType="Float" Precision="8" Format="HDF">{h5name}:/contact/coordinates</DataItem>
      </Geometry>
      <Attribute Name="pressure" AttributeType="Scalar" Center="Node">
        <DataItem Dimensions="{m}" NumberType="Float" Precision="8" Format="HDF">{h5name}:/contact/pressure</DataItem>
      </Attribute>
      <Attribute Name="slip" AttributeType="Scalar" Center="Node">
        <DataItem Dimensions="{m}" NumberType="Float" Precision="8" Format="HDF">{h5name}:/contact/slip</DataItem>
      </Attribute>
      <Attribute Name="status" AttributeType="Scalar" Center="Node">
        <DataItem Dimensions="{m}" NumberType="Int" Precision="1" Format="HDF">{h5name}:/contact/status</DataItem>
      </Attribute>
    </Grid>""" if m else ""
    text = f"""<?xml version="1.0" ?>
<Xdmf Version="3.0">
  <Domain>
    <Grid Name="body" GridType="Uniform">
      <Topology TopologyType="Hexahedron" NumberOfElements="{nc}" NodesPerElement="8">
        <DataItem Dimensions="{nc} 8" NumberType="Int" Precision="8" Format="HDF">{h5name}:/mesh/topology</DataItem>
      </Topology>
      <Geometry GeometryType="XYZ">
        <DataItem Dimensions="{n} 3" NumberType="Float" Precision="8" Format="HDF">{h5name}:/mesh/coordinates</DataItem>
      </Geometry>
      <Attribute Name="displacement" AttributeType="Vector" Center="Node">
        <DataItem Dimensions="{n} 3" NumberType="Float" Precision="8" Format="HDF">{h5name}:/fields/displacement</DataItem>
      </Attribute>
    </Grid>{grid_contact}
  </Domain>
</Xdmf>
"""
    _write_text(path, text)


def _write_text(path, text):
    with open(path, "w") as f:
        f.write(text)


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


FORMATS = ("h5", "xdmf", "json")


def parse_formats(text):
    """-output_formats h5,xdmf,json (default all; 'none': no file): a tuple of FORMATS."""
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


def write_results(problem, outdir, summary, formats=FORMATS):
    """The files of `formats` (solution.h5, solution.xdmf, summary.json); collective,
    rank 0 writes; nothing is gathered for files not asked for."""
    comm = problem.comm.tompi4py()
    if not formats:
        return
    nodes = gather_nodes(problem) if "h5" in formats else None
    contact = gather_contact(problem) if "h5" in formats else None
    err = None
    if comm.rank == 0:
        names = {"h5": "solution.h5", "xdmf": "solution.xdmf", "json": "summary.json"}
        paths = {k: os.path.join(outdir, names[k]) for k in FORMATS if k in formats}
        try:
            with Staged(*paths.values()) as tmp:
                if "h5" in paths:
                    write_hdf5(tmp[paths["h5"]], nodes, contact)
                if "xdmf" in paths:
                    write_xdmf(tmp[paths["xdmf"]], "solution.h5", nodes[0].shape[0],
                               nodes[2].shape[0], contact["pressure"].shape[0])
                if "json" in paths:
                    _write_text(tmp[paths["json"]], json.dumps(summary, indent=2) + "\n")
        except OSError as e:
            err = f"cannot write results to {outdir}: {e.strerror or e}"
    err = comm.bcast(err, root=0)
    if err:
        raise OSError(err)
