"""A contact pair of two deformable bodies, condensed to the one-body problem by a change of
basis (dual mortar, fem/mortar.py).

The dual mortar couples the slave surface's nodes j to the master's nodes l through the
diagonal D (D_j = int N_j: the lumped weight of contactset.py) and M; the relative
displacement at slave node j is the mortar projection
    g_j(u) = u_j - sum_l P_jl u_l,     P = D^-1 M  (each row normalised to sum 1)
and the multiplier lambda_j acts on the slave node with D_j and on the master nodes with
-M_jl. The change of basis u = Z u~, Z = I + E, E the rows of P (slave row, master column,
in each of the 3 components), makes the slave unknowns the relative displacements
(u~_j = g_j(u)) and leaves every other unknown as it was; with A~ = Z^T A Z and b~ = Z^T b,
the slave rows of A~ u~ - b~ are D lambda and the master rows hold R_m + P^T R_s, the
multiplier's reaction on the master eliminated node by node (the condensation of Popp, Gee
& Wall 2009, section 4, and of Hueber & Wohlmuth 2005). So the contact set on the slave
nodes, with the gap n . (X_j - sum_l P_jl X_l), is that of a body on a rigid foundation:
the Newton iteration, its globalisation, its residuals and the paper's loops run unchanged
on (A~, b~). Energies are the same in both bases (u~ . A~ u~ = u . A u, b~ . u~ = b . u);
the displacement is Z u~ (`to_displacement`).

The slave face's outward normal is +e_k or -e_k; n = -e_k is read through D, -1 on the
slave nodes' k dof (Z = D + E): u~_k = n . g_j, so the contact set's normal is +e_k either
way (`sign` turns its output back). Z^-1 = D - D E, for the rigid-body near-nullspace of
A~ (GAMG), the coarse-to-fine start and the multigrid's finest interpolation: (D + E)(D -
D E) = D^2 - D^2 E + E D - E D E = I - E + E D - E D E, and E D = E, E D E = E E = 0
where E's columns (master nodes) are none of its rows (slave nodes), D being -1 at slave
nodes only.

Several pairs (a stack of blocks): E is the sum of each pair's, D flips each pair's slave
nodes where its n = -e_k. That stays Z = D + E with the inverse above as long as no node is
the slave node of two pairs (E's rows would add) and no slave node of one pair is a master
node of another (E E = 0); pairs_crosspoints.check_nodes refuses the latter (PairError,
one line naming the two pairs). A node on two pairs' slave faces (a crosspoint) is the
first pair's; the later pair's dual basis takes it in at its neighbours k, whose rows of Z
then hold the crosspoint's too (pairs_crosspoints.py: Z^-1 = D (I + G) built from its own
entries G). Each pair has its own normal (+-e_k, any k): the contact set reads each node's
normal dof (contactset.py: `axes`).

A slave face that is not one plane normal to x, y or z (curved, or flat and tilted) has a
basis Q_j of its own at each slave node, n_j its averaged normal (pairs_curved.py): D's
+-1 become the blocks Q_j^T, the contact set reads n_j . g_j on the node's dof 2 and the
gap is n_j . (X_j - sum_l P_jl X_l); no crosspoints; q2 faces where each one's edges
are straight seen along its own normal (a cylinder's, not a sphere's).

Rows and columns of clamped dofs are left out of E: a clamped slave component stays u~ = u
(0), a clamped master component contributes its 0.

A~ is assembled as it stands (fem/assembly.py, `add_turned`): Z differs from D only at the
slave nodes, so only the cells that hold one change; each rank sums its such cells'
element matrices on their nodes (A_t, scipy) and adds Z_t^T A_t Z_t, Z_t being Z's rows
at those nodes, into A~'s rows of the cells' nodes and the master nodes they couple to
(global indices: any rank's), which `pattern` preallocates. The one-body stiffness (BAIJ)
then holds, and so does the multigrid's rediscretised first coarse operator (multigrid.py):
(Z^-1 P)^T A~ (Z^-1 P) = P^T A P. PETSc's product Z^T A Z (`transform_matrix`), into AIJ
with Galerkin coarse operators, was the way before; it is the tests' reference now
(runs/results/two-bodies.md: the times of both).

The q2 element (fem/mortar_q2.py): the surfaces come as the refined mesh's quadrilaterals;
each rank puts its own together into 9-node faces (the 4 of an element face are one rank's:
the children of one cell) before they are gathered, and the mortar couples those (D_j the
Gauss-Lobatto weights of contactset.py on a flat face, 1/36, 4/36, 16/36 of its area where
it is a parallelogram). The faces' edges must be straight seen along the pair's normal
(the mortar clips their corners' quadrilaterals; graded boxes and a lower_surface seen
along z are), the edge nodes in their middle halves: PairError otherwise.

Set-up only: the two surfaces (global vertex numbers and coordinates, small against the
mesh) are gathered on every rank, each rank integrates a share of the mortar matrices and
every rank holds their sum, the same on every rank (mortar_matrices' comm) (and the
same clamped dofs of the pair's nodes: which of E's entries are left out does not depend
on the partition), and each assembles its own rows of Z.
"""
from collections import namedtuple

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact.fem import pairs_crosspoints as crosspoints
from contact.fem import pairs_curved as curved
from contact.fem.assembly import orthonormal_nullspace
from contact.fem.mortar import mortar_matrices
from contact.fem.mortar_q2 import edge_bends, nine_node_faces
from contact.fem.pairs_crosspoints import PairError  # noqa: F401  (pairs.PairError)
from contact.mesh import Q1_ROLE

#: a slave node whose mortar row sum is below this fraction of D_j is left out of the pair
#: (a sliver of master over it: the dual basis's row there is ill-conditioned)
MIN_COVER = 1e-3
#: q2: the pair's 9-node faces, seen along its normal, have straight edges to this fraction
#: of an edge's length (the mortar clips the corners' quadrilaterals: fem/mortar_q2.py)
STRAIGHT_TOL = 1e-8


def _gathered(comm, gidx, coords, faces, k=4):
    """(x (n, 3), faces (nf, k) into x, global vertex numbers (n,)) of a surface whose
    local faces are `faces` (k nodes each: 4, or the q2 element's 9), on every rank."""
    mine = (gidx[faces], coords[faces])
    parts = comm.tompi4py().allgather(mine)
    g = np.concatenate([p[0].reshape(-1, k) for p in parts]).astype(np.int64)
    X = np.concatenate([p[1].reshape(-1, 3) for p in parts])
    ids, first, inv = np.unique(g.ravel(), return_index=True, return_inverse=True)
    return X[first], inv.reshape(-1, k), ids


def _nine_node(comm, surfaces, roles):
    """The q2 element's surfaces: each one's slave and master as 9-node faces (fem/mortar_q2.py,
    from the refined quadrilaterals and the vertices' roles), but a q1 body's (its vertices'
    role Q1_ROLE on every rank: a q1 body beside q2 bodies) as they are; PairError on every
    rank where one rank's faces are not whole element faces."""
    mpi = comm.tompi4py()

    def faces(quads):
        q2 = mpi.allreduce(bool(np.any(roles[np.asarray(quads, dtype=np.int64)] != Q1_ROLE)),
                           op=MPI.LOR)
        return nine_node_faces(quads, roles) if q2 else quads
    out, err = [], None
    for s in surfaces:
        try:
            out.append(s._replace(slave=faces(s.slave), master=faces(s.master)))
        except ValueError as e:
            err = err or f"contact pair {s.name!r}: {e}"
    errs = [e for e in comm.tompi4py().allgather(err) if e]
    if errs:
        raise PairError(errs[0])
    return out


def _in_place(apply, v):
    """v <- apply(v, out) through a work Vec; returns v."""
    t = v.duplicate()
    apply(v, t)
    t.copy(v)
    t.destroy()
    return v


def _held(comm, clamped, nodes):
    """The clamped dofs (global) of the vertices `nodes` (global numbers), every rank's:
    whether E leaves out an entry must not hang on which rank owns its column."""
    cl = np.asarray(clamped, dtype=np.int64)
    parts = comm.tompi4py().allgather(cl[np.isin(cl // 3, nodes)])
    return np.unique(np.concatenate(parts))


#: one contact pair's surfaces: name (its contact part), slave and master (local faces (nf,
#: 4), counter-clockwise about their body's outward normal), the slave's outward normal
#: sign e_axis (axis None: a curved or tilted slave face, a basis per node: pairs_curved.py)
Surface = namedtuple("Surface", "name slave master axis sign")


class ContactPair:
    """The change of basis Z = I + E of one or several contact pairs, E the sum of each
    pair's (module docstring).

    dm, coords: the mesh; surfaces: a Surface per pair; clamped: global clamped rows;
    roles: the q2 element's vertex roles (hierarchy.QuadraticCells; the surfaces' faces are
    then its refined quadrilaterals, coupled as 9-node faces: fem/mortar_q2.py), or None;
    taken: (label, global vertex numbers) of the rigid foundation's contact nodes, which
    keep their crosspoints with the pairs (pairs_crosspoints.py), or None."""

    def __init__(self, dm, coords, surfaces, clamped, roles=None, taken=None):
        comm = dm.getComm()
        self.comm = comm
        if roles is not None:
            surfaces = _nine_node(comm, surfaces, roles)
        g = dm.createGlobalVec()
        self._rows, self.n_nodes = g.getOwnershipRange(), g.getSize() // 3
        g.destroy()
        gidx = np.asarray(dm.getLGMap().getBlockIndices(), dtype=np.int64)
        parts = [self._surface(comm, gidx, coords, s, clamped) for s in surfaces]
        #: the crosspoints' couplings (pairs_crosspoints.py: a node on two pairs' slave
        #: faces is the first's; the later's dual basis takes it in at its neighbours)
        self._moved = crosspoints.take(parts, taken)
        bent = [p for p in parts if p["Q"] is not None]
        if bent and self._moved:
            raise PairError(f"contact pair {bent[0]['name']!r}: a curved or tilted slave face "
                            f"may not meet another pair's or the foundation's contact face")
        ids = np.concatenate([p["rows"] for p in bent] + [np.zeros(0, dtype=np.int64)])
        order = np.argsort(ids)
        #: the slave nodes with a basis of their own (sorted) and their Q_j (pairs_curved.py)
        self._curved = (ids[order], np.concatenate([p["Q"][p["ok"]] for p in bent] +
                                                   [np.zeros((0, 3, 3))])[order])
        self._parts = parts
        crosspoints.check_nodes(parts)
        #: the normal n into the slave bodies (the foundation's normal of a one-body scene;
        #: several pairs: the first's, each pair's own in `pairs`; a curved pair's: its
        #: nodes' mean) and the contact set's normal dof there
        self.normal, self.axis = parts[0]["normal"], parts[0]["axis"]
        #: per pair: name, normal, its covered slave nodes and all its slave face's nodes
        #: (global vertex numbers)
        self.pairs = [{"name": p["name"], "normal": p["normal"], "slave_ids": p["rows"],
                       "n_slave": int(p["rows"].size), "slave_face": p["sid"],
                       "axis": p["axis"], "extra": p.get("extra"),
                       "normals": p["N"]} for p in parts]
        cat = lambda k: np.concatenate([p[k] for p in parts])           # noqa: E731
        #: per slave face node (global vertex number): whether the master covers it, and
        #: its gap n . (X_j - sum_l P_jl X_l)
        self.slave_ids, self.covered, self.gaps = cat("sid"), cat("ok"), cat("gaps")
        self.n_slave = int(self.covered.sum())
        #: d = -1 on the slave nodes' axis dof where n = -e_axis (u~ . e_axis = n . g_j),
        #: so that the contact set reads n as +e_axis (contactset.py; `signs` for output)
        self._flipped = np.concatenate([p["rows"] for p in parts if p["d"] < 0] +
                                       [np.zeros(0, dtype=np.int64)])
        srow, mcol, v = cat("srow"), cat("mcol"), cat("v")
        order = np.argsort(srow, kind="stable")                      # E's rows in order
        held = _held(comm, clamped, np.union1d(self.slave_ids, cat("mid")))
        flip = np.concatenate([3 * p["rows"] + s.axis for p, s in zip(parts, surfaces)
                               if p["d"] < 0] + [np.zeros(0, dtype=np.int64)])
        E = self._coupling(srow[order], mcol[order], v[order], held)
        if self._moved:
            d_of = lambda ids: np.where(np.isin(3 * ids[:, None] + np.arange(3), flip),  # noqa
                                        -1.0, 1.0)
            E, self._g = crosspoints.extend(E, self._moved, d_of, held, self.n_nodes)
        else:                                              # Z^-1 = D - D E
            self._g = (E[0], E[1], -E[2], E[3])
        self._turning(E, np.sort(cat("rows")), flip)
        self.Z, self.Zinv = (self._assemble(flip, inverse) for inverse in (False, True))

    @staticmethod
    def _surface(comm, gidx, coords, s, clamped):
        """One pair's mortar coupling (gathered surfaces: every rank the same): its slave
        face nodes `sid`, which the master covers `ok`, their gaps, E's entries (srow,
        mcol, v: global vertex numbers, P_jl), E's rows and columns, the master face
        nodes `mid`, the normal n into the slave body and d (-1 where n = -e_axis); a
        curved pair (s.axis None): its nodes' bases Q and normals N (pairs_curved.py)."""
        xs, fs, sid = _gathered(comm, gidx, coords, s.slave, s.slave.shape[1])
        xm, fm, mid = _gathered(comm, gidx, coords, s.master, s.master.shape[1])
        if 9 in (fs.shape[1], fm.shape[1]):     # (each side 4 or 9 nodes: q1 or q2 bodies)
            (o1, m1), (o2, m2) = (edge_bends(X, s.axis) if X.shape[1] == 9 else (0.0, True)
                                  for X in (xs[fs], xm[fm]))
            if max(o1, o2) > STRAIGHT_TOL or not (m1 and m2):
                raise PairError(f"contact pair {s.name!r}: q2 needs faces whose edges, seen "
                                f"along the pair's normal (curved: each face's), are "
                                f"straight (an edge node off "
                                f"its edge by {max(o1, o2):.1e} of it) with the edge nodes "
                                f"in their middle halves; use -element q1")
        mt = mortar_matrices(xs, fs, xm, fm, comm=comm.tompi4py(), axis=s.axis)
        rowsum = np.bincount(mt.rows, mt.values, minlength=xs.shape[0])
        ok = rowsum > MIN_COVER * np.maximum(mt.D, 1e-300)
        keep = ok[mt.rows]
        r, c, v = mt.rows[keep], mt.cols[keep], mt.values[keep] / rowsum[mt.rows[keep]]
        proj = np.zeros((xs.shape[0], 3))
        np.add.at(proj, r, v[:, None] * xm[c])
        Q = N = None
        if s.axis is None:
            held = np.isin(3 * sid[:, None] + np.arange(3), _held(comm, clamped, sid))
            Q, N, normal = curved.surface_bases(s.name, xs, mt.normals, held, mt.D)
            gaps = np.einsum("ij,ij->i", xs - proj, N)
        else:
            normal = np.zeros(3)
            normal[s.axis] = -float(s.sign)
            gaps = (xs - proj) @ normal
        # touching faces: a gap of rounding size has the sign of the summation order, which
        # the partition sets (the surfaces are gathered in rank order); 0 it is, so that the
        # first Newton step's active set is the same on every partition (8 ranks: a node
        # open at +1e-17 took one more step than on 1)
        scale = max(np.abs(xs).max(initial=0.0), np.abs(xm).max(initial=0.0), 1e-300)
        gaps[np.abs(gaps) <= 64.0 * np.finfo(float).eps * scale] = 0.0
        return {"name": s.name, "faces": fs, "xs": xs, "D": mt.D,       # (crosspoints)
                "sid": sid, "ok": ok, "gaps": gaps, "srow": sid[r],
                "mcol": mid[c], "v": v, "rows": sid[ok], "cols": np.unique(mid[c]),
                "mid": mid, "normal": normal, "d": -1.0 if s.sign > 0 else 1.0, "Q": Q,
                "N": N, "axis": 2 if Q is not None else s.axis}

    def weight_off(self, nv_owned, rstart_block):
        """Per owned vertex, what the contact set's lumped weight holds too much at the
        crosspoints (pairs_crosspoints.py), or None without crosspoints."""
        if not self._moved:
            return None
        return crosspoints.weight_off(self._moved, self._parts, nv_owned, rstart_block)

    def clamped_rows(self, rows):
        """The clamped rows (global, x, y, z) in the loops' basis: a clamped component of a
        curved pair's slave node is the dof of its basis that is that axis (pairs_curved.py)."""
        return curved.clamped_rows(*self._curved, rows).astype(PETSc.IntType)

    def bases(self, ids, components):
        """(m, 3, 3): per contact node (global vertex numbers ids, the contact set's
        components), row c the direction of its contact-space component c in x, y, z: the
        axes, or a curved pair's Q_j; None without curved pairs (contactset's axes)."""
        return curved.bases(*self._curved, ids, components)

    def signs(self, ids):
        """D's entry on the normal dof of the slave nodes `ids` (global vertex numbers):
        -1 where their pair's n = -e_axis, else 1 (the contact set's `sign`)."""
        return np.where(np.isin(ids, self._flipped), -1.0, 1.0)

    def _coupling(self, srow, mcol, val, held):
        """E by node: (slave node, master node, P_jm, (n, 3) the components kept) of each
        entry, the components of a clamped slave or master dof left out (held: the
        clamped dofs of the pair's nodes, all ranks'; the module docstring)."""
        keep = ~np.isin(3 * srow[:, None] + np.arange(3), held)
        keep &= ~np.isin(3 * mcol[:, None] + np.arange(3), held)
        return srow, mcol, val, keep

    def _turning(self, coupling, nodes, flip):
        """Z's rows at the slave nodes `nodes` (global, sorted) in padded node arrays, for
        turning element matrices (element_matrices): the master nodes (-1 padded), P_jm
        per component kept, and D's diagonal (-1 at the dofs `flip`)."""
        srow, mcol, val, keep = self._e = coupling
        self._nodes = nodes
        at = np.searchsorted(nodes, srow)
        slot = np.arange(srow.size) - np.searchsorted(srow, srow)     # (srow sorted)
        width = int(slot.max()) + 1 if slot.size else 1
        self._masters = np.full((nodes.size, width), -1, dtype=np.int64)
        self._weights = np.zeros((nodes.size, width, 3))
        self._masters[at, slot] = mcol
        self._weights[at, slot] = (val if val.ndim == 2 else val[:, None]) * keep
        self._d = np.ones((nodes.size, 3))
        self._d[np.searchsorted(nodes, flip // 3), flip % 3] = -1.0

    def _assemble(self, flip, inverse):
        """Z = D + E (inverse: Z^-1 = D - D E) as an AIJ Mat (block size 3), D the diagonal
        of 1 and -1 (at the dofs `flip`)."""
        (lo, hi), N = self._rows, 3 * self.n_nodes
        srow, mcol, val, keep = self._g if inverse else self._e
        k = np.nonzero(keep)
        rows, cols = 3 * srow[k[0]] + k[1], 3 * mcol[k[0]] + k[1]
        vals = val[k] if val.ndim == 2 else val[k[0]]      # (per component: crosspoints)
        d = np.ones(hi - lo)
        d[flip[(flip >= lo) & (flip < hi)] - lo] = -1.0
        mine = (rows >= lo) & (rows < hi)
        rows, cols, vals = rows[mine], cols[mine], vals[mine]
        if inverse:                                        # Z^-1 = D (I + G)
            vals = d[rows - lo] * vals
        dr, dv, (ids, Q) = np.arange(lo, hi), d, self._curved
        dc = dr
        if ids.size:                       # curved pairs' blocks Q_j^T (Z^-1: Q_j, -P_jl Q_j)
            if inverse:
                rows, cols, vals = curved.turned_rows(ids, Q, rows, cols, vals)
            flat = ~np.isin(dr // 3, ids)
            br, bc, bv = curved.diagonal_blocks(ids, Q, lo, hi, inverse)
            dr, dc, dv = (np.concatenate([x[flat], y]) for x, y in ((dr, br), (dr, bc),
                                                                   (d, bv)))
        # CSR of the owned rows: D and E's entries (columns sorted per row)
        allr, allc, allv = (np.concatenate(x) for x in ((dr, rows), (dc, cols), (dv, vals)))
        order = np.lexsort((allc, allr))
        allr, allc, allv = allr[order], allc[order], allv[order]
        indptr = np.concatenate([[0], np.cumsum(np.bincount(allr - lo, minlength=hi - lo))])
        Z = PETSc.Mat().createAIJ(size=((hi - lo, N), (hi - lo, N)), bsize=3,
                                  csr=(indptr.astype(PETSc.IntType),
                                       allc.astype(PETSc.IntType), allv), comm=self.comm)
        Z.assemble()
        return Z

    def turns(self, cells):
        """Which cells (global vertex numbers, (m, a)) hold a slave node: their element
        matrices are turned (add_turned)."""
        return np.isin(cells, self._nodes).any(axis=1)

    def _local_basis(self, cells, nodal=False):
        """Z's rows at the nodes of `cells` (global vertex numbers, (m, a)) as a CSR matrix
        (scipy) on (rows: those nodes, columns: them and the master nodes of their slave
        nodes; sorted global vertex numbers, 3 dofs each). nodal: one dof per node, every
        entry 1 (Z's node pattern)."""
        from scipy import sparse           # (here: a one-body run loads no scipy, 9 MiB)
        rows = np.unique(cells)
        at = np.minimum(np.searchsorted(self._nodes, rows), max(self._nodes.size - 1, 0))
        slave = np.flatnonzero(self._nodes[at] == rows) if self._nodes.size else at[:0]
        mast = self._masters[at[slave]]                                    # (s, K), -1 pad
        cols = np.union1d(rows, mast[mast >= 0])
        i, j = np.nonzero(mast >= 0)
        r = np.concatenate([np.arange(rows.size), slave[i]])
        c = np.concatenate([np.searchsorted(cols, rows), np.searchsorted(cols, mast[i, j])])
        if nodal:
            return rows, cols, sparse.csr_matrix((np.ones(r.size), (r, c)),
                                                 shape=(rows.size, cols.size))
        d = np.ones((rows.size, 3))
        d[slave] = self._d[at[slave]]
        ids, Q = self._curved
        k = np.flatnonzero(np.isin(rows, ids))                 # curved: blocks Q_j^T
        d[k] = 0.0
        v = np.concatenate([d, self._weights[at[slave]][i, j]])
        dof = np.arange(3)
        br, bc, bv = curved.blocks(k, np.searchsorted(cols, rows[k]),
                                   Q[np.searchsorted(ids, rows[k])].transpose(0, 2, 1))
        Z = sparse.csr_matrix((np.concatenate([v.ravel(), bv]),
                               (np.concatenate([(3 * r[:, None] + dof).ravel(), br]),
                                np.concatenate([(3 * c[:, None] + dof).ravel(), bc]))),
                              shape=(3 * rows.size, 3 * cols.size))
        return rows, cols, Z

    def _turned(self, cells, Ke=None):
        """(nodes, R): R = Z^T A_t Z on the nodes `nodes` (global, sorted), A_t the sum of
        the element matrices Ke (m, 3 a, 3 a) of `cells` (global vertex numbers, (m, a)):
        the blocks these cells give A~ = Z^T A Z (u = Z u~ on their dofs and on those of
        the master nodes their slave nodes couple to), as a scipy BSR matrix of 3 x 3
        blocks; Ke None: R's node pattern (CSR, one entry per block)."""
        from scipy import sparse
        rows, cols, Z = self._local_basis(cells, nodal=Ke is None)
        m, a = cells.shape
        k = 1 if Ke is None else 3
        dof = (k * np.searchsorted(rows, cells)[:, :, None] + np.arange(k)).reshape(m, k * a)
        At = sparse.csr_matrix((np.ones(m * a * a) if Ke is None else Ke.ravel(),
                                (np.repeat(dof, k * a, axis=1).ravel(),
                                 np.tile(dof, (1, k * a)).ravel())),
                               shape=(Z.shape[0], Z.shape[0]))
        if Ke is None:
            return cols, Z.T.tocsr() @ (At @ Z)
        # the product of 3 x 3 block matrices (scipy's bsr_matmat): the same values as the
        # CSR product's and its conversion to BSR, 4.6x faster (Nd 8 two blocks: 1.02 ->
        # 0.22 s, runs/results/two-bodies.md)
        Zb, Ab = (X.tobsr(blocksize=(3, 3)) for X in (Z, At))
        return cols, Zb.T.tobsr(blocksize=(3, 3)) @ (Ab @ Zb)

    def pattern(self, cells):
        """The (row, column) node pairs (global) that the cells among `cells` (m, a) at
        slave nodes add to A~, as keys row * n + column (n: the global node count)."""
        cells = cells[self.turns(cells)]
        if cells.shape[0] == 0:
            return np.zeros(0, dtype=np.int64)
        nodes, R = self._turned(cells)
        rows = np.repeat(nodes, np.diff(R.indptr))
        return rows * self.n_nodes + nodes[R.indices]

    def add_turned(self, A, cells, Ke, chunk=4096):
        """Adds to A (ADD_VALUES, global block indices: the coupled master nodes may be any
        rank's) the blocks of A~ = Z^T A Z that the element matrices Ke (m, 3 a, 3 a) of
        cells (global vertex numbers, (m, a)) at slave nodes give (preallocated:
        pattern); the rows in chunks of `chunk` nodes (padded arrays)."""
        if cells.shape[0] == 0:
            return
        nodes, R = self._turned(cells, Ke)
        n = np.diff(R.indptr)
        for r0 in range(0, nodes.size, chunk):
            r1 = min(r0 + chunk, nodes.size)
            k = n[r0:r1]
            W = int(k.max()) if k.size else 0
            cols = np.full((r1 - r0, W), -1, dtype=PETSc.IntType)
            vals = np.zeros((r1 - r0, W, 3, 3))
            i = np.repeat(np.arange(r1 - r0), k)
            j = np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k)
            blk = slice(R.indptr[r0], R.indptr[r1])
            cols[i, j] = nodes[R.indices[blk]]
            vals[i, j] = R.data[blk]
            A.setValuesBlockedRCV(nodes[r0:r1, None].astype(PETSc.IntType), cols,
                                  vals.transpose(0, 2, 1, 3).reshape(r1 - r0, -1),
                                  addv=PETSc.InsertMode.ADD_VALUES)

    def transform_matrix(self, A):
        """A~ = Z^T A Z by PETSc's product (a new Mat; A is left as it is): the reference
        of the stiffness assembled in this basis (element_matrices; tests)."""
        return A.ptap(self.Z)          # (petsc_compat: ptap on 3.18 and 3.26)

    def transform_load(self, b):
        """In place: b <- Z^T b."""
        return _in_place(self.Z.multTranspose, b)

    def to_displacement(self, xt, out=None):
        """u = Z u~ (a new Vec unless `out`)."""
        out = xt.duplicate() if out is None else out
        self.Z.mult(xt, out)
        return out

    def from_displacement(self, u):
        """In place: u <- Z^-1 u."""
        return _in_place(self.Zinv.mult, u)

    def vertex_gaps(self, nv_owned, rstart_block):
        """(gap per owned vertex, covered mask per owned vertex): the pair's gaps at the
        owned slave vertices (0 elsewhere), and which slave vertices the master covers."""
        gap = np.zeros(nv_owned)
        cov = np.zeros(nv_owned, dtype=bool)
        loc = self.slave_ids - rstart_block
        mine = (loc >= 0) & (loc < nv_owned)
        gap[loc[mine]] = self.gaps[mine]
        cov[loc[mine]] = self.covered[mine]
        return gap, cov

    def vertex_axes(self, nv_owned, rstart_block):
        """Per owned vertex, the axis k of its pair's normal (+-e_k) at the slave face
        vertices, -1 elsewhere (the contact set's normal dofs: contactset.py)."""
        out = np.full(nv_owned, -1, dtype=np.intp)
        for p in self.pairs:
            loc = p["slave_face"] - rstart_block
            out[loc[(loc >= 0) & (loc < nv_owned)]] = p["axis"]
        return out

    def from_displacement_rows(self, P):
        """Z^-1 P (a new Mat): an interpolation into x, y, z turned into this basis (the
        multigrid's finest one, multigrid.py)."""
        return self.Zinv.matMult(P)

    def rigid_body_nullspace(self, coordinates, body_masks):
        """The near-nullspace of A~: each body's six rigid modes (body_masks: a Vec per
        body, 1 on its dofs), in u~ (Z^-1), orthonormalised."""
        base = PETSc.NullSpace().createRigidBody(coordinates)
        vecs = []
        for mask in body_masks:
            for r in base.getVecs():
                v = r.copy()
                v.pointwiseMult(v, mask)
                vecs.append(self.from_displacement(v))
        base.destroy()
        return orthonormal_nullspace(vecs, coordinates.getComm())
