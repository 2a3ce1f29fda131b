"""Cell labels through refinement (hierarchy.py): the gmsh physical groups' face bitmasks
("physical:<group>", gmshio.py), the CAD surfaces' ("cad:<body>:<surface>", cad.py) and
the bodies' ("body", mesh/bodies.py) copied onto an uninterpolated mesh, and the face
bitmasks kept exact across DMRefine."""
import numpy as np
from petsc4py import PETSc

from contact import mesh
from contact.mesh.plex import BODY_LABEL, HEX_FACES

#: the prefixes of the cell labels whose value is a bitmask of faces (bit k: HEX_FACES[k])
FACE_LABELS = ("physical:", "cad:")


def copy_cell_labels(src, dst):
    """The face labels (FACE_LABELS: "physical:*", "cad:*", mesh.labelled_faces) and the
    bodies' ("body", bodies.py) of src on dst, whose cells are src's, in the same numbering
    (DMPlexUninterpolate drops labels)."""
    cs, ce = src.getHeightStratum(0)
    for i in range(src.getNumLabels()):
        name = src.getLabelName(i)
        if not (name.startswith(FACE_LABELS) or name == BODY_LABEL):
            continue
        dst.createLabel(name)
        out = dst.getLabel(name)
        label = src.getLabel(name)
        for v in label.getValueIS().getIndices():
            pts = label.getStratumIS(int(v)).getIndices()
            cells = pts[(pts >= cs) & (pts < ce)].astype(PETSc.IntType)
            is_ = PETSc.IS().createGeneral(cells, comm=PETSc.COMM_SELF)
            out.setStratumIS(int(v), is_)
            is_.destroy()


def _face_labels(dm):
    return [n for n in (dm.getLabelName(i) for i in range(dm.getNumLabels()))
            if n.startswith(FACE_LABELS)]


def mark_surfaces(dm, u):
    """Before a file mesh is refined: a label "surface:<name>" on the interpolated dm with
    the faces of each face label <name> (FACE_LABELS) and their edges and vertices. DMRefine
    hands a labelled point's value to every point made from it, so on each finer mesh this
    label holds the group's faces, edges and vertices there: the cell label alone cannot
    say that (each of a marked cell's 8 children inherits its bitmask, though
    only some of their faces lie on the group; surface_masks mends them). A loop over the
    file mesh's marked cells, once."""
    conn = mesh.cell_vertices(u)[0]
    vs, ve = dm.getDepthStratum(0)
    for name in _face_labels(u):
        cells, k = mesh.labelled_cell_faces(u, name)
        want = {}
        for c, kk in zip(cells.tolist(), k.tolist()):
            want.setdefault(c, []).append(frozenset((conn[c, HEX_FACES[kk]] + vs).tolist()))
        sname = "surface:" + name
        dm.createLabel(sname)
        label = dm.getLabel(sname)
        for c, faces in want.items():
            for f in dm.getCone(c):
                pts = dm.getTransitiveClosure(f)[0]
                if frozenset(p for p in pts.tolist() if vs <= p < ve) in faces:
                    for p in pts.tolist():
                        label.setValue(p, 1)


def surface_masks(dm, u):
    """The bitmasks of u's face labels ("physical:<group>", "cad:*") on a refined level
    (u: dm's cells and vertices): face k of a marked cell is in the group when its 4
    vertices are on the group's surface ("surface:<label>", mark_surfaces). Exact for the
    children of a marked cell: of their faces, those inside the parent hold its centre,
    which is not on the surface, and those on a parent face not in the group hold that
    face's centre."""
    conn = mesh.cell_vertices(u)[0]
    vs, ve = dm.getDepthStratum(0)
    cs, ce = u.getHeightStratum(0)
    for name in _face_labels(u):
        on = np.zeros(ve - vs, dtype=bool)
        sl = dm.getLabel("surface:" + name)
        if sl.getStratumSize(1):
            pts = sl.getStratumIS(1).getIndices()
            on[pts[(pts >= vs) & (pts < ve)] - vs] = True
        label = u.getLabel(name)
        cells = np.unique(np.concatenate(
            [np.zeros(0, dtype=np.intp)] + [label.getStratumIS(int(v)).getIndices()
                                            for v in label.getValueIS().getIndices()]))
        cells = cells[(cells >= cs) & (cells < ce)] - cs
        mask = (np.all(on[conn[cells][:, HEX_FACES]], axis=2)
                << np.arange(6)).sum(axis=1) if cells.size else np.zeros(0, dtype=int)
        u.removeLabel(name)
        u.createLabel(name)
        label = u.getLabel(name)
        for v in np.unique(mask[mask > 0]):
            is_ = PETSc.IS().createGeneral((cells[mask == v] + cs).astype(PETSc.IntType),
                                           comm=PETSc.COMM_SELF)
            label.setStratumIS(int(v), is_)
            is_.destroy()
