"""A scene's contact pairs and what stands beside them, set up on a Discretisation
(discretisation.py): the pairs' surfaces into one change of basis (pairs.py), the rigid
foundation's contact parts beside them, a contact part's own friction. Set-up only; every
refusal is a SceneError in one line, raised on every rank alike."""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact import fem
from contact.fem.contactset import friction_values
from contact.fem.pairs import ContactPair, PairError, Surface
from contact.mesh import bodies as mesh_bodies
from contact.scene import AXES, SceneError, foundation_normal


def owned_on(disc, names):
    """Which owned vertices lie on a face of the boundary parts `names` (bool, per owned
    vertex), and the first owned vertex's global number."""
    loc = np.zeros((disc.coords.shape[0], 3))
    for name in names:
        loc[np.unique(disc.parts[name].ravel()), 0] = 1.0
    g = fem.local_to_global(disc.dm, loc.ravel())
    on = g.getArray(readonly=True)[::3] > 0.0
    start = g.getOwnershipRange()[0] // 3
    g.destroy()
    return on, start


def slave_side(disc, name, part):
    """(axis k, sign s) of a pair's slave faces (disc.parts[name], on the mesh's places)
    where they are one plane normal to e_k, the body's outward normal s e_k; (None, 0)
    otherwise: a curved or tilted slave face, a basis per node (fem/pairs_curved.py)."""
    mpi, faces, X = disc.comm.tompi4py(), disc.parts[name], disc.coords
    n = fem.face_normals(faces, X)
    k = int(np.argmax(np.abs(mpi.allreduce(n.sum(axis=0)))))
    s = np.sign(mpi.allreduce(n[:, k].sum()))
    at = X[faces][:, :, k] if faces.size else np.zeros((0, 4))
    lo = mpi.allreduce(at.min(initial=np.inf), op=MPI.MIN)
    hi = mpi.allreduce(at.max(initial=-np.inf), op=MPI.MAX)
    off = mpi.allreduce(float(np.max(1.0 - s * n[:, k], initial=0.0)), op=MPI.MAX)
    size = mpi.allreduce(float(np.ptp(X, axis=0).max(initial=0.0)), op=MPI.MAX)
    if s == 0 or off > 1e-8 or hi - lo > 1e-9 * max(size, 1e-300):
        return None, 0
    return k, int(s)


def contact_pairs(disc, pairs):
    """The contact pairs [(name, part)] of the Discretisation disc as one change of basis
    (fem/pairs.py): each part's faces the slave side (slave_side), the faces of its
    master.body on master.plane (found on the unmapped boxes) or its physical group
    master.physical (a gmsh body's) the master side."""
    names, surfaces = list(disc.bodies), []
    for name, part in pairs:
        m = part["master"]
        axis, sign = slave_side(disc, name, part)
        if "physical" in m:
            master = disc.part_faces(name, {"body": m["body"], "physical": m["physical"]},
                                     disc.conn, disc.coords)
        else:
            master = mesh_bodies.body_faces(disc.conn, disc.level.reference, disc.body_of,
                                            names.index(m["body"]), AXES[m["plane"][0]],
                                            float(m["plane"][1]))
            if disc.comm.tompi4py().allreduce(master.shape[0]) == 0:
                raise SceneError(f"contact pair {name!r}: body {m['body']!r} has no cell "
                                 f"face on the plane {m['plane'][0]} = {m['plane'][1]}")
        surfaces.append(Surface(name, disc.parts[name], master, axis, sign))
    try:
        pair = ContactPair(disc.dm, disc.coords, surfaces, disc.clamped, disc.roles,
                           taken=foundation_nodes(disc))
    except PairError as e:
        raise SceneError(str(e)) from None
    for (name, part), p in zip(pairs, pair.pairs):
        if p["n_slave"] == 0:
            raise SceneError(f"contact pair {name!r}: the master faces of "
                             f"{part['master']['body']!r} never face the slave faces of "
                             f"{part['body']!r}")
    return pair


def foundation_nodes(disc):
    """(label, global vertex numbers) of the rigid foundation's contact parts beside the
    pairs (every rank's), or None: their nodes on a pair's slave faces are crosspoints the
    foundation keeps (fem/pairs_crosspoints.py)."""
    names = [n for n, p in disc.scene["boundary"].items() if p["type"] == "contact" and
             "master" not in p]
    if not names:
        return None
    on, start = owned_on(disc, names)
    ids = disc.comm.tompi4py().allgather(start + np.flatnonzero(on))
    return (f"contact part {names[0]!r} (the rigid foundation)",
            np.unique(np.concatenate(ids)))


def foundation_beside_pairs(disc, names, gap, covered, axes):
    """The owned vertices of the rigid foundation's contact parts `names` join a scene's
    contact pairs' contact set (gap, covered, axes: per owned vertex, the pairs', changed
    in place): the gap to the foundation's plane, whose normal must be an axis +e_k (the
    contact set's normal dof k), none of them a pair's slave node (its crosspoints with a
    pair the pair has left to it: foundation_nodes); SceneError naming the parts
    otherwise. Returns the bodies the foundation holds (their names); sets
    disc.foundation_points and disc.foundation_normal (for the rigid-motion checks)."""
    comm = disc.comm.tompi4py()
    n = np.asarray(foundation_normal(disc.scene), dtype=float)
    axis = int(np.argmax(np.abs(n)))
    if not np.array_equal(n, np.eye(3)[axis]):
        raise SceneError(f"contact part {names[0]!r}: beside contact pairs the foundation's "
                         f"normal must be +x, +y or +z, got {[float(c) for c in n]}")
    on, start = owned_on(disc, names)
    ids = start + np.flatnonzero(on)
    shared = comm.allreduce(np.array([np.isin(ids, p["slave_face"]).sum()
                                      for p in disc.pair.pairs])) > 0     # (summed)
    if shared.any():
        raise SceneError(f"contact part {names[0]!r} (the rigid foundation) and contact pair "
                         f"{disc.pair.pairs[int(np.argmax(shared))]['name']!r} share slave "
                         f"nodes: a node may be in one contact part only")
    xyz = disc.coordinates.getArray(readonly=True).reshape(-1, 3)
    point = np.asarray(disc.scene.get("contact", {}).get("foundation", {})
                       .get("point", [0.0, 0.0, 0.0]), dtype=float)
    gap[on] = (xyz[on] - point) @ n
    covered[on] = True
    axes[on] = axis
    disc.foundation_points, disc.foundation_normal = xyz[on].copy(), n
    vb = np.full(disc.coords.shape[0], -1, dtype=np.intp)
    vb[disc.conn] = disc.body_of[:, None]
    held = np.unique(np.concatenate([vb[disc.parts[nm].ravel()] for nm in names]))
    bodies = list(disc.bodies)
    return {bodies[i] for part in comm.allgather(held) for i in part if i >= 0}


def part_friction(disc):
    """A contact part's own `friction:` (a number or an expression in x, y, z, as
    contact.friction; several bodies) on its owned contact nodes, in place of the scene's
    there (the contact set's F)."""
    cs, bnd = disc.cs, disc.scene["boundary"]
    own = [(n, p["friction"]) for n, p in bnd.items() if p["type"] == "contact" and
           "friction" in p]
    if not own or cs is None:
        return
    F = cs.local_array(cs.F)
    err = None
    for name, spec in own:
        on, _ = owned_on(disc, [name])
        mine = on[cs.nodes]
        try:
            F[mine] = friction_values(spec, cs.coordinates[mine])
        except ValueError as e:
            err = err or f"boundary part {name!r}: {e}"
        if not np.all(np.isfinite(F[mine]) & (F[mine] >= 0.0)):
            err = err or f"boundary part {name!r}: friction {spec!r} must be finite and >= 0"
    errs = [e for e in disc.comm.tompi4py().allgather(err) if e]     # every rank raises
    if errs:
        raise SceneError(errs[0])
    cs.F.setArray(F)
    cs.has_friction = cs.F.norm(PETSc.NormType.INFINITY) > 0.0
