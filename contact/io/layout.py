"""Where the results' rows are: the canonical order of a problem's nodes, cells, contact
nodes and contact faces, and the data gathered on rank 0.

The order does not depend on the partition: nodes and contact nodes sorted by (z, y, x)
(nodes then by body, where two bodies' nodes share a place),
cells and faces by their sorted node numbers. `Layout` holds it as canonical.Order's (a
parallel sample sort) for the files all ranks write together (output.py): a field is
moved there by a VecScatter, nothing gathered. Tests and scripts gather on rank 0 in the
same order (`gather_nodes`, `canonical_order`; output.gather_contact); the figures
(figures.py) gather `figure_data` on rank 0 for them only: the contact face and the
body's surface, small next to the volume.
"""
import numpy as np

from contact.analysis import stress
from contact.mesh.canonical import Order
from contact.mesh import HEX_FACES

#: PETSc hexahedron vertex order -> VTK/XDMF hexahedron order
PETSC_TO_VTK_HEX = np.array([0, 3, 2, 1, 4, 5, 6, 7])


# -- gathered on rank 0, in the canonical order (tests, scripts) -----------------------------
def _gatherv(comm, a):
    parts = comm.gather(np.ascontiguousarray(a), root=0)
    return np.concatenate(parts) if comm.rank == 0 else None


def canonical_order(xyz, body=None):
    """Permutation sorting points by (z, y, x), then by body (nodes of two bodies may share
    a place: scene_bodies.py)."""
    keys = (xyz[:, 0], xyz[:, 1], xyz[:, 2])
    return np.lexsort(keys if body is None else (body,) + keys)


def gather_nodes(problem, x=None):
    """On rank 0: coordinates (n,3), displacement (n,3), cells (nc,8) in canonical order
    (for tests and scripts; the files do not gather)."""
    comm = problem.comm.tompi4py()
    x = problem.to_xyz(x) if x is not None else problem.displacement()
    xyz = problem.coordinates.getArray(readonly=True).reshape(-1, 3)
    u = x.getArray(readonly=True).reshape(-1, 3)
    rstart = problem.coordinates.getOwnershipRange()[0] // 3
    gid = rstart + np.arange(xyz.shape[0])
    lg = problem.dm.getLGMap().getBlockIndices()              # local vertex -> global node
    cells = lg[problem.conn] if problem.conn.size else np.zeros((0, 8), dtype=int)
    body = problem.disc.node_bodies()
    XYZ, U, GID, CELLS, BODY = (_gatherv(comm, a) for a in (xyz, u, gid, cells, body))
    if comm.rank != 0:
        return None
    order = canonical_order(XYZ, BODY)
    canon = np.empty(GID.max() + 1, dtype=np.int64)
    canon[GID[order]] = np.arange(order.size)
    C = canon[CELLS]
    C = C[np.lexsort(np.sort(C, axis=1).T[::-1])]              # cells in a canonical order too
    return XYZ[order], U[order], C


def gather_state(comm, state):
    """A contact state's arrays gathered on rank 0, in canonical order."""
    keys = [k for k in state if k not in ("w", "F")] + ["w", "F"]
    data = {k: _gatherv(comm, state[k]) for k in keys}
    if comm.rank != 0:
        return None
    order = canonical_order(data["coordinates"])
    return {k: v[order] for k, v in data.items()}


# -- the canonical layout of one problem (the files) -----------------------------------------
def _orient(q):
    """Quadrilaterals (f, 4) turned to start at their smallest number and run toward the
    smaller neighbour: the same rows whatever the cells' vertex order."""
    if q.shape[0] == 0:
        return q
    i = np.argmin(q, axis=1)
    r = q[np.arange(q.shape[0])[:, None], (i[:, None] + np.arange(4)) % 4]
    flip = r[:, 3] < r[:, 1]
    r[flip] = r[flip][:, [0, 3, 2, 1]]
    return r


def contact_names(problem):
    """The scene's contact parts, in its order (that of contact_faces)."""
    return [n for n, p in problem.scene["boundary"].items() if p["type"] == "contact"]


def contact_faces(problem):
    """Local faces (f, 4) of the scene's contact parts (local vertex numbers)."""
    faces = [problem.parts[n] for n in contact_names(problem)]
    return np.concatenate(faces) if faces else np.zeros((0, 4), dtype=np.intp)


class Layout:
    """The canonical orders (canonical.Order) of a problem's nodes, cells, contact nodes
    and contact faces; collective."""

    def __init__(self, problem):
        comm, dm = problem.comm, problem.dm
        mpi = comm.tompi4py()
        xyz = problem.coordinates.getArray(readonly=True).reshape(-1, 3)
        first = problem.coordinates.getOwnershipRange()[0] // 3
        self.nodes = Order(comm, np.column_stack([xyz[:, ::-1], problem.disc.node_bodies()]),
                           first + np.arange(xyz.shape[0]))
        number = self.nodes.to_source(self.nodes.offset + np.arange(self.nodes.count))
        vid = np.rint(stress.local_values(dm, np.repeat(number, 3, axis=1))[:, 0])
        cells = vid.astype(np.int64)[problem.conn]
        nc = cells.shape[0]
        self.cells = Order(comm, np.sort(cells, axis=1), (mpi.exscan(nc) or 0) + np.arange(nc),
                           cells[:, PETSC_TO_VTK_HEX])
        self.contact = self.faces = None
        cs = problem.cs
        if cs is not None and cs.size:
            first = cs.template.getOwnershipRange()[0]
            c = self.contact = Order(comm, cs.coordinates[:, ::-1],
                                     first + np.arange(cs.local_size))
            number = c.to_source(c.offset + np.arange(c.count))
            owned = np.full((xyz.shape[0], 3), -1.0)
            owned[cs.nodes] = number
            cid = np.rint(stress.local_values(dm, owned)[:, 0]).astype(np.int64)
            q = cid[contact_faces(problem)]
            q = _orient(q[np.all(q >= 0, axis=1)])
            self.faces = Order(comm, np.sort(q, axis=1), np.zeros(q.shape[0]), q)

    @property
    def sizes(self):
        c, f = self.contact, self.faces
        return {"nodes": self.nodes.total, "cells": self.cells.total,
                "contact": c.total if c else 0, "faces": f.total if f else 0}

    def destroy(self):
        for o in (self.nodes, self.cells, self.contact, self.faces):
            if o is not None:
                o.destroy()


# -- figures' data (gathered on rank 0) ------------------------------------------------------
def surface(problem, body, u=None):
    """On rank 0: the body's boundary faces as corners X (f, 4, 3), displacements U (f, 4, 3)
    and the von Mises stress of their cells (f,). Each rank sends its cells' faces that no
    other local cell shares (the boundary and the partition interfaces); rank 0 drops the
    faces sent twice (interfaces)."""
    comm = problem.comm.tompi4py()
    u = problem.displacement() if u is None else u
    ul = stress.local_values(problem.dm, u.getArray(readonly=True).reshape(-1, 3))
    conn, coords = problem.conn, problem.coords
    faces = conn[:, HEX_FACES].reshape(-1, 4)
    cell = np.repeat(np.arange(conn.shape[0]), 6)
    lg = problem.dm.getLGMap().getBlockIndices()
    keys = np.sort(lg[faces], axis=1)
    if keys.shape[0]:
        _, first, count = np.unique(keys, axis=0, return_index=True, return_counts=True)
        once = first[count == 1]
    else:
        once = np.zeros(0, dtype=np.intp)
    f = faces[once]
    ind = problem.error_indicator[0] if problem.error_indicator is not None else None
    parts = [_gatherv(comm, a) for a in (keys[once], coords[f], ul[f],
                                         body["cell_von_mises"][cell[once]])]
    eta = _gatherv(comm, ind[cell[once]]) if ind is not None else None
    if comm.rank:
        return None
    K, X, U, vm = parts
    if K.shape[0]:
        _, inv, count = np.unique(K, axis=0, return_inverse=True, return_counts=True)
        keep = count[inv.ravel()] == 1
        X, U, vm = X[keep], U[keep], vm[keep]
        eta = eta[keep] if eta is not None else None
    return {"X": X.reshape(-1, 4, 3), "U": U.reshape(-1, 4, 3), "von_mises": vm,
            "error_indicator": eta}


def _contact_parts(problem, summary):
    """With several bodies and several contact parts (pairs, the foundation beside them):
    [{name, normal (+e_k of the part's plane), result (a pair's contact_result, else
    None)}] in contact_faces' order, each drawn on its own (figures.py); else None."""
    names = contact_names(problem)
    if problem.scene.get("bodies") is None or len(names) < 2:
        return None
    pairs = summary.get("contact_pairs") or {}
    out = []
    for n in names:
        e = np.zeros(3)
        e["xyz".index(problem.scene["boundary"][n]["plane"][0])] = 1.0
        out.append({"name": n, "normal": e,
                    "result": (pairs.get(n) or {}).get("contact_result")})
    return out


def figure_data(problem, summary):
    """Everything figures.py draws, on rank 0 (None elsewhere); collective."""
    comm = problem.comm.tompi4py()
    st = stress.final(problem)
    surf = surface(problem, st["body"])
    contact = faces = face_parts = None
    if st["contact"] is not None:
        contact = gather_state(comm, st["contact"])
        corners = _gatherv(comm, problem.coords[contact_faces(problem)])
        face_parts = _gatherv(comm, np.concatenate(
            [np.full(problem.parts[n].shape[0], k, dtype=np.int64)
             for k, n in enumerate(contact_names(problem))] or [np.zeros(0, np.int64)]))
        if comm.rank == 0:
            faces = corners.reshape(-1, 4, 3)
    if comm.rank:
        return None
    steps = getattr(problem, "increments", None) or []
    return {"name": summary.get("scene", "scene"), "nd": summary.get("nd"),
            "element": summary.get("element", "q1"),
            "normal": np.asarray(problem.normal, dtype=float),
            "point": np.asarray(problem.scene.get("contact", {}).get("foundation", {})
                                .get("point", [0.0, 0.0, 0.0]), dtype=float),
            "friction": problem.scene.get("contact", {}).get("friction", 0.0),
            "surface": surf, "contact": contact, "contact_faces": faces,
            "contact_face_parts": face_parts, "contact_parts": _contact_parts(problem, summary),
            "von_mises_max": summary.get("von_mises_max"),
            "error_indicator": summary.get("error_indicator"),
            "contact_result": summary.get("contact_result"),
            "steps": [{"t": s["t"], **s["resultant"]} for s in steps]}
