"""Hexahedral meshes from gmsh (.geo or .msh) through the gmsh Python API.

Rank 0 reads (and for a .geo, meshes) the file with gmsh, keeps the 8-node hexahedra and
builds a serial-on-rank-0 uninterpolated DMPlex (cells in PETSc's cone order, see
`contact.mesh.HEX_REF`), like `mesh.create_box_mesh`; `mesh.distribute` spreads it.
Every physical surface group becomes a DMLabel "physical:<name>" on the cells whose value
is the bitmask of the cell's faces in the group (bit k <=> `mesh.HEX_FACES[k]`);
`mesh.labelled_faces` turns it back into faces after distribution.

`parameters` are set as gmsh parser numbers before the file is merged (gmsh.merge, not
gmsh.open, which clears them), so they override `DefineConstant[ nd = {...} ];` (and
`If (!Exists(nd)) ... EndIf`), not plain `nd = 4;` assignments (reported as an error).
Cells are taken as gmsh orders them: an inverted hexahedron in a .msh stays inverted
(`mesh.check_cells` reports it).

A .geo (or any file with a CAD geometry, not gmsh's "Discrete" entities: a .msh has none)
with a curved surface (not "Plane") also gives, per boundary surface entity of its
hexahedra, its faces' bitmask (`read_rank0`'s 4th value; the cell labels "cad:<body>:<tag>"
of cad.py), and `Geometry` opens that model again to project refined vertices onto its
surfaces and curves (cad.py, on every rank).

gmsh is imported only here, and only on rank 0 to read, when a scene uses a gmsh mesh (and,
to snap the refined levels of a curved .geo, on every rank: cad.py).
"""
import contextlib
import os

import numpy as np
from petsc4py import PETSc

from contact.mesh import HEX_FACES, MeshError

#: gmsh's 8-node hexahedron, nodes 0..7 at (-1,-1,-1) (1,-1,-1) (1,1,-1) (-1,1,-1)
#: (-1,-1,1) (1,-1,1) (1,1,1) (-1,1,1): PETSc's cone position j holds gmsh node GMSH_TO_PETSC[j]
GMSH_TO_PETSC = np.array([0, 3, 2, 1, 4, 5, 6, 7], dtype=np.intp)

_HEX, _QUAD = 5, 3
_VOLUME_TYPES = {4: "tetrahedra", 5: "hexahedra", 6: "prisms", 7: "pyramids",
                 11: "10-node tetrahedra", 12: "27-node hexahedra", 13: "18-node prisms",
                 14: "14-node pyramids", 17: "20-node hexahedra", 18: "15-node prisms",
                 19: "13-node pyramids"}


def _face_masks(conn, groups, path, strict=True):
    """Per group (name, quads (nq, 4) vertex indices, -1 = not a hex vertex): the (nc,)
    bitmask of the hex faces the quads are. A quad on two cells marks the first one.
    A quad that is no hexahedron's face: MeshError if strict, else left out."""
    nc = conn.shape[0]
    faces = np.sort(conn[:, HEX_FACES], axis=2).reshape(-1, 4)        # (6 nc, 4)
    quads = [np.sort(q, axis=1) for _, q in groups]
    _, inv = np.unique(np.concatenate([faces] + quads), axis=0, return_inverse=True)
    inv = inv.ravel()
    first = np.full(inv.max() + 1 if inv.size else 0, 6 * nc, dtype=np.int64)
    np.minimum.at(first, inv[:6 * nc], np.arange(6 * nc))
    masks, start = {}, 6 * nc
    for (name, _), q in zip(groups, quads):
        hit = first[inv[start:start + q.shape[0]]]
        start += q.shape[0]
        miss = int(np.count_nonzero((hit == 6 * nc) | np.any(q < 0, axis=1)))
        if miss and strict:
            raise MeshError(f"mesh {path}: {miss} of the {q.shape[0]} faces of physical "
                            f"surface '{name}' are not faces of its hexahedra")
        hit = hit[(hit < 6 * nc) & np.all(q >= 0, axis=1)]
        mask = masks.setdefault(name, np.zeros(nc, dtype=np.int64))
        np.bitwise_or.at(mask, hit // 6, np.left_shift(1, hit % 6))
    return masks


@contextlib.contextmanager
def _model(path, parameters, verbose):
    """gmsh (the module) with the file merged into a model of its own, removed after (gmsh
    finalized if this opened it)."""
    import gmsh

    if not os.path.isfile(path):
        raise MeshError(f"mesh file {path} does not exist")
    owner = not gmsh.isInitialized()
    if owner:
        gmsh.initialize(readConfigFiles=False, interruptible=False)
    else:
        gmsh.model.add("contact.mesh.gmshio")
    try:
        gmsh.option.setNumber("General.Terminal", 1 if verbose else 0)
        for name, value in (parameters or {}).items():
            gmsh.parser.setNumber(str(name), [float(value)])
        try:
            gmsh.merge(path)         # gmsh.open would clear the parser variables set above
        except Exception as e:       # gmsh raises bare Exception with its last error
            raise MeshError(f"gmsh cannot read {path}: {e}") from None
        yield gmsh
    finally:
        if owner:
            gmsh.finalize()
        else:
            gmsh.model.remove()


def _curved(gmsh, dim, tag, samples=17):
    """Whether entity (dim, tag) has a CAD shape that is not flat: not gmsh's "Discrete"
    (a .msh's), "Plane" or "Line", and its parametrisation's values on a grid of samples^dim
    points not on one plane (a surface) or line (a curve) to 1e-10 of its extent (a .geo's
    transfinite "Surface" may well be a plane)."""
    kind = gmsh.model.getType(dim, tag)
    if kind.startswith("Discrete") or kind in ("Plane", "Line"):
        return False
    lo, hi = gmsh.model.getParametrizationBounds(dim, tag)
    axes = [np.linspace(a, b, samples) for a, b in zip(lo, hi)]
    u = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, dim)
    x = np.asarray(gmsh.model.getValue(dim, tag, u.ravel().tolist())).reshape(-1, 3)
    sv = np.linalg.svd(x - x.mean(axis=0), compute_uv=False)
    return bool(sv[dim] > 1e-10 * sv[0])


def read_rank0(path, parameters, verbose):
    """(cells (nc, 8) PETSc order, coords (nv, 3), {group name: (nc,) face bitmask},
    {surface entity tag: (nc,) face bitmask}) of the file on this process (rank 0 of
    read_gmsh; a gmsh body: mesh/bodies.py). The last is empty unless the file's geometry
    has a curved surface (then it holds every surface entity with faces: cad.py)."""
    with _model(path, parameters, verbose) as gmsh:
        if path.endswith(".geo"):
            for name, value in (parameters or {}).items():
                got = gmsh.parser.getNumber(str(name))
                if len(got) != 1 or got[0] != float(value):
                    raise MeshError(f"mesh {path}: parameter {name} = {value} not taken "
                                    f"(use DefineConstant[ {name} = ... ]; in the .geo)")
        types = gmsh.model.mesh.getElements(3)[0]
        if len(types) == 0:
            try:
                gmsh.model.mesh.generate(3)
            except Exception as e:
                raise MeshError(f"gmsh cannot mesh {path}: {e}") from None
        types, _, enodes = gmsh.model.mesh.getElements(3)
        other = {int(t): len(n) // gmsh.model.mesh.getElementProperties(t)[3]
                 for t, n in zip(types, enodes) if t != _HEX}
        if other:
            what = ", ".join(f"{_VOLUME_TYPES.get(t, f'gmsh type {t}')}: {n}"
                             for t, n in other.items())
            raise MeshError(f"mesh {path}: {sum(other.values())} cells are not 8-node "
                            f"hexahedra ({what}); recombine the mesh (Mesh.RecombineAll, "
                            f"Mesh.SubdivisionAlgorithm 2) or use transfinite volumes")
        hexes = [np.asarray(n, dtype=np.int64) for t, n in zip(types, enodes) if t == _HEX]
        if not hexes:
            raise MeshError(f"mesh {path} has no hexahedra (a .msh with physical groups "
                            f"needs one on the volume too, or Mesh.SaveAll 1)")
        hexes = np.concatenate(hexes).reshape(-1, 8)
        ntags, ncoords, _ = gmsh.model.mesh.getNodes()
        ntags = np.asarray(ntags, dtype=np.int64)
        order = np.argsort(ntags)
        used = np.unique(hexes)                                   # gmsh tags -> 0..nv-1
        coords = np.asarray(ncoords, dtype=float).reshape(-1, 3)[
            order[np.searchsorted(ntags[order], used)]]
        cells = np.searchsorted(used, hexes)[:, GMSH_TO_PETSC]   # PETSc's cone order

        groups = []
        for dim, tag in gmsh.model.getPhysicalGroups(2):
            name = gmsh.model.getPhysicalName(dim, tag) or str(tag)
            q = np.concatenate([_quads(gmsh, dim, ent, path, name).ravel() for ent in
                                gmsh.model.getEntitiesForPhysicalGroup(dim, tag)] +
                               [np.zeros(0, dtype=np.int64)])
            groups.append((name, _indices(used, q).reshape(-1, 4)))
        entities = []
        if any(_curved(gmsh, 2, t) for _, t in gmsh.model.getEntities(2)):
            for _, tag in gmsh.model.getEntities(2):
                q = _quads(gmsh, 2, tag, path, None).ravel()
                if q.size:
                    entities.append((tag, _indices(used, q).reshape(-1, 4)))
        cad = _face_masks(cells, [(f"surface {t}", q) for t, q in entities], path, False)
        return (cells, coords, _face_masks(cells, groups, path),
                {t: cad[f"surface {t}"] for t, _ in entities})


def _quads(gmsh, dim, ent, path, name):
    """The gmsh node tags (n, 4) of entity (dim, ent)'s quadrilaterals (those of physical
    group `name`: MeshError for any other face; name None: the quadrilaterals alone)."""
    quads = [np.zeros(0, dtype=np.int64)]
    for t, n in zip(*gmsh.model.mesh.getElements(dim, ent)[::2]):
        if t != _QUAD and name is None:
            continue
        if t != _QUAD:
            raise MeshError(f"mesh {path}: physical surface '{name}' has "
                            f"faces that are not 4-node quadrilaterals")
        quads.append(np.asarray(n, dtype=np.int64))
    return np.concatenate(quads).reshape(-1, 4)


def _indices(used, q):
    """Positions of gmsh node tags q in used (sorted), -1 where absent."""
    pos = np.minimum(np.searchsorted(used, q), used.size - 1)
    return np.where(used[pos] == q, pos, -1)


class Geometry:
    """A file's CAD model on this process (any rank), for cad.py: which entities are
    curved, the curves two surfaces share, and points projected onto an entity. Use as a
    context manager: `with Geometry(path, parameters) as g: ...`."""

    #: Gauss-Newton steps after gmsh's closest point, and their stop (in the parameters)
    STEPS, TOL = 20, 1e-14

    def __init__(self, path, parameters):
        self._cm = _model(str(path), parameters, False)

    def __enter__(self):
        self.gmsh = self._cm.__enter__()
        return self

    def __exit__(self, *exc):
        return self._cm.__exit__(*exc)

    def curved(self, dim, tag):
        return _curved(self.gmsh, dim, tag)

    def shared_curves(self, s1, s2):
        """The tags of the curves on the boundary of both surfaces s1 and s2."""
        ends = [{abs(t) for _, t in self.gmsh.model.getBoundary([(2, s)], oriented=False)}
                for s in (s1, s2)]
        return sorted(ends[0] & ends[1])

    def parameters(self, dim, tag, x):
        """The parameters (n, dim) on entity (dim, tag) of its points nearest x (n, 3):
        gmsh's closest point's, made orthogonal by Gauss-Newton steps on the
        parametrisation (gmsh's own is approximate on a built-in kernel's surface: 3e-4 off
        on meshes/ball.geo); for points on the entity, theirs to rounding."""
        model = self.gmsh.model
        if x.shape[0] == 0:
            return np.zeros((0, dim))
        u = np.asarray(model.getClosestPoint(dim, tag, x.ravel().tolist())[1],
                       dtype=float).reshape(-1, dim)
        lo, hi = (np.asarray(b, dtype=float) for b in model.getParametrizationBounds(dim, tag))
        for _ in range(self.STEPS):
            d = np.asarray(model.getDerivative(dim, tag, u.ravel().tolist())).reshape(-1, dim, 3)
            A = np.einsum("nai,nbi->nab", d, d)
            r = x - self.value(dim, tag, u)
            step = np.linalg.solve(A, np.einsum("nai,ni->na", d, r)[..., None])[..., 0]
            u = np.clip(u + step, lo, hi)
            if np.abs(step).max(initial=0.0) <= self.TOL * np.max(hi - lo):
                break
        return u

    def value(self, dim, tag, u):
        """The points (n, 3) of entity (dim, tag) at parameters u (n, dim)."""
        if u.shape[0] == 0:
            return np.zeros((0, 3))
        return np.asarray(self.gmsh.model.getValue(dim, tag, u.ravel().tolist())).reshape(-1, 3)


def read_gmsh(comm, path, parameters=None):
    """Serial-on-rank-0 DMPlex of the 8-node hexahedra of a gmsh .geo/.msh file.

    `parameters` (name -> number) override the .geo's DefineConstant values. Returns
    (dm, names): names of the physical surface groups (unnamed: the tag), each with a
    cell label "physical:<name>" = bitmask of the cell's faces in the group. Errors are
    MeshError on every rank.
    """
    mpi = comm.tompi4py()
    data, err = None, None
    if comm.getRank() == 0:
        verbose = PETSc.Options().getBool("gmsh_verbose", False)
        try:
            data = read_rank0(str(path), parameters, verbose)
        except MeshError as e:
            err = str(e)
        except Exception as e:     # anything else on rank 0 must not leave the others hanging
            err = f"cannot read mesh {path}: {type(e).__name__}: {e}"
    err = mpi.bcast(err, root=0)
    if err:
        raise MeshError(err)
    if data is not None:
        cells, coords, masks, cad = data
    else:
        cells, coords, masks, cad = np.zeros((0, 8)), np.zeros((0, 3)), {}, {}
    names, tags = mpi.bcast((list(masks), sorted(cad)), root=0)
    dm = PETSc.DMPlex().createFromCellList(3, np.asarray(cells, dtype=PETSc.IntType),
                                           np.asarray(coords, dtype=PETSc.RealType),
                                           interpolate=False, comm=comm)
    for name in names:
        mask_label(dm, "physical:" + name, masks.get(name))
    for tag in tags:                                 # a curved CAD: cad.py
        mask_label(dm, cad_label(0, tag), cad.get(tag))
    return dm, names


def cad_label(body, tag):
    """The cell label of the faces on surface entity `tag` of body index `body` (cad.py)."""
    return f"cad:{body}:{tag}"


def mask_label(dm, name, mask):
    """The cell label `name` (created on every rank) with value mask[c] on cell c where
    it is not 0 (mask None: no cell here)."""
    dm.createLabel(name)
    if mask is None:
        return
    label, cs = dm.getLabel(name), dm.getHeightStratum(0)[0]
    for v in np.unique(mask[mask > 0]):             # at most 63 values
        pts = (np.flatnonzero(mask == v) + cs).astype(PETSc.IntType)
        is_ = PETSc.IS().createGeneral(pts, comm=PETSc.COMM_SELF)
        label.setStratumIS(int(v), is_)
        is_.destroy()
