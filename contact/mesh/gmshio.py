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

gmsh is imported only here, and only on rank 0, when a scene uses a gmsh mesh.
"""
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


def _face_masks(conn, groups, path):
    """Per group (name, quads (nq, 4) vertex indices, -1 = not a hex vertex): the (nc,)
    bitmask of the hex faces the quads are. A quad on two cells marks the first one."""
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
        if miss:
            raise MeshError(f"mesh {path}: {miss} of the {q.shape[0]} faces of physical "
                            f"surface '{name}' are not faces of its hexahedra")
        mask = masks.setdefault(name, np.zeros(nc, dtype=np.int64))
        np.bitwise_or.at(mask, hit // 6, np.left_shift(1, hit % 6))
    return masks


def read_rank0(path, parameters, verbose):
    """(cells (nc, 8) PETSc order, coords (nv, 3), {group name: (nc,) face bitmask}) of
    the file on this process (rank 0 of read_gmsh; a gmsh body: mesh/bodies.py)."""
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
            quads = [np.zeros(0, dtype=np.int64)]
            for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
                for t, n in zip(*gmsh.model.mesh.getElements(2, ent)[::2]):
                    if t != _QUAD:
                        raise MeshError(f"mesh {path}: physical surface '{name}' has "
                                        f"faces that are not 4-node quadrilaterals")
                    quads.append(np.asarray(n, dtype=np.int64))
            q = np.concatenate(quads)
            pos = np.minimum(np.searchsorted(used, q), used.size - 1)
            groups.append((name, np.where(used[pos] == q, pos, -1).reshape(-1, 4)))
        return cells, coords, _face_masks(cells, groups, path)
    finally:
        if owner:
            gmsh.finalize()
        else:
            gmsh.model.remove()


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
        cells, coords, masks = data
    else:
        cells, coords, masks = np.zeros((0, 8)), np.zeros((0, 3)), {}
    names = mpi.bcast(list(masks), root=0)
    dm = PETSc.DMPlex().createFromCellList(3, np.asarray(cells, dtype=PETSc.IntType),
                                           np.asarray(coords, dtype=PETSc.RealType),
                                           interpolate=False, comm=comm)
    cs = dm.getHeightStratum(0)[0]
    for name in names:
        dm.createLabel("physical:" + name)
        mask = masks.get(name)
        if mask is None:
            continue
        label = dm.getLabel("physical:" + name)
        for v in np.unique(mask[mask > 0]):             # at most 63 values
            pts = (np.flatnonzero(mask == v) + cs).astype(PETSc.IntType)
            is_ = PETSc.IS().createGeneral(pts, comm=PETSc.COMM_SELF)
            label.setStratumIS(int(v), is_)
            is_.destroy()
    return dm, names
