"""What a solution means to an engineer: the stress in the body and the contact tractions.

Stress (Q1, sigma = lambda tr(eps) I + 2 mu eps, eps = sym grad u), components in the
order of VTK's symmetric tensors (ParaView names them so): xx, yy, zz, xy, yz, xz.
  per cell   the cell mean of the 2x2x2 Gauss values, weighted by |J| w:
             int_e sigma dx / |e| by the element's own quadrature (exact for the
             trilinear field's constant part; a constant stress is reproduced exactly);
  per node   the volume-weighted average of the adjacent cells' means,
             sum_e |e| sigma_e / sum_e |e| over the cells holding the node;
  von Mises  sqrt(((s_xx-s_yy)^2 + (s_yy-s_zz)^2 + (s_zz-s_xx)^2)/2 + 3 (s_xy^2+s_yz^2+s_xz^2))
             of the cell mean (per cell) and of the nodal average (per node).
Shape-function gradients are fem/element.py's (`fem.geometry`); all cells at once (NumPy over
chunks of fem.CHUNK cells). q2 (fem/element.py): the cells are the refined mesh's, each an eighth
of a 27-node element; a cell's mean is that of the element's quadratic field over the
eighth (2x2x2 Gauss points of the eighth, in the element's reference coordinates), so a
linear stress is reproduced exactly in every eighth's mean; q2p1's volumetric part is its
projected divergence's (the element's pressure), averaged over the eighth the same way.

Contact (per owned contact node j, from the reaction R = A u - b of residuals.py; in x, y, z):
  traction         t_j = R_j / w_j, the force per area of the foundation on the body
  normal_traction  t_j . n = g_j (residuals.tractions), the pressure from the reaction
  pressure         l_j, the loops' multiplier (equal to g_j to the loops' tolerance)
  friction         |sigma_tau,j|, the friction force per area
  friction_use     |sigma_tau,j| / (F_j g_j) in contact with F_j > 0 (1: at the Coulomb
                   bound, slipping), else 0
  slip             |du_tau| of the last load increment (the whole u for a static run)
  status           0 separated (l_j = 0), 1 stick, 2 slip (slip > 1e-6 max |du|)
  normal_displacement      -u_nu = u . n (> 0: away from the foundation)
  tangential_displacement  |u_tau| of the whole displacement
Resultants: sum_j R_j (in x, y, z), its normal part N = n . sum_j R_j and tangential part;
areas: sum_j w_j over the contact nodes of each status.
"""
import weakref

import numpy as np
from petsc4py import PETSc

from contact import fem
from contact.fem import element
from contact.solvers import residuals as res
from contact.geometry import basis

#: stress components, in this order (VTK's symmetric tensor order)
COMPONENTS = ("xx", "yy", "zz", "xy", "yz", "xz")
_I, _J = np.array([0, 1, 2, 0, 1, 0]), np.array([0, 1, 2, 1, 2, 2])
STATUS = ("separated", "stick", "slip")


def von_mises(s):
    """von Mises stress of stresses s (..., 6) in COMPONENTS order."""
    return np.sqrt(0.5 * ((s[..., 0] - s[..., 1]) ** 2 + (s[..., 1] - s[..., 2]) ** 2
                          + (s[..., 2] - s[..., 0]) ** 2)
                   + 3.0 * (s[..., 3] ** 2 + s[..., 4] ** 2 + s[..., 5] ** 2))


def _octant_rules():
    """q2: for each eighth o = 4 ox + 2 oy + oz of the reference cube, the rule (dN,
    dN^T, w) of its 2x2x2 Gauss points for fem.geometry."""
    g = element._GP3 / 2.0
    rules = []
    for o in range(8):
        lo = np.array([o // 4, (o // 2) % 2, o % 2], dtype=float)
        _, dn = fem.q2_shape(lo - 0.5 + g)
        rules.append(((dn, np.ascontiguousarray(dn.transpose(0, 2, 1)), np.full(8, 0.125)),
                      lo - 0.5 + g))
    return rules


_OCTANTS = _octant_rules()


def cell_stress(X, U, lam, mu, rule=None, theta=None):
    """Cell-mean Cauchy stress (c, 6) and volumes (c,) of cells X (c, a, 3) with nodal
    displacements U (c, a, 3): the Gauss values (the element's rule, or `rule`: see
    fem.geometry) averaged with weights |J| w. theta (c,): the cells' mean volumetric
    strain where an element projects it (q2p1), in place of the mean of tr eps."""
    dNdx, wdet = fem.geometry(X, rule)
    vol = wdet.sum(axis=1)
    a = X.shape[1]
    g = np.matmul(wdet[:, None, :], dNdx.reshape(X.shape[0], -1, 3 * a)).reshape(-1, a, 3)
    H = np.matmul(U.transpose(0, 2, 1), g) / vol[:, None, None]   # mean grad u (matmul:
    # einsum is ~10x slower)
    eps = 0.5 * (H + H.transpose(0, 2, 1))
    sig = 2.0 * mu * eps
    tr = np.trace(eps, axis1=1, axis2=2)
    m = mu.reshape(-1) if np.ndim(mu) else mu                      # (a material per cell)
    vol_part = lam * tr if theta is None else (lam + 2.0 * m / 3.0) * theta - 2.0 * m / 3.0 * tr
    sig[:, [0, 1, 2], [0, 1, 2]] += vol_part[:, None]
    return sig[:, _I, _J], vol


def _projected_theta(coords, ul, conn, m):
    """(ne, 8): each element's projected divergence (fem.projected_divergence, m pressure
    functions) averaged over each of its eighths (_OCTANTS), for elements conn (ne, 27)
    with local displacements ul; the projection once per element."""
    theta = np.zeros((conn.shape[0], 8))
    for a in range(0, conn.shape[0], fem.CHUNK // 8):
        X, U = coords[conn[a:a + fem.CHUNK // 8]], ul[conn[a:a + fem.CHUNK // 8]]
        dNdx, wdet = fem.geometry(X)
        Dq, Mh = fem.projected_divergence(X, dNdx, wdet, m, with_mass=True)
        coef = np.einsum("cmn,cnak,cak->cm", Mh, Dq, U)          # theta = q . coef
        for o, (rule, points) in enumerate(_OCTANTS):
            _, w8 = fem.geometry(X, rule)
            q8 = fem.pressure_basis(X, wdet, m, points=points)
            theta[a:a + X.shape[0], o] = np.einsum("cgm,cm,cg->c", q8, coef, w8) / w8.sum(axis=1)
    return theta


def local_values(dm, owned):
    """(nv, 3) values at the local (owned + ghost) vertices of owned (n, 3) values."""
    g = dm.createGlobalVec()
    g.setArray(np.ascontiguousarray(owned, dtype=float).ravel())
    lvec = dm.getLocalVec()
    dm.globalToLocal(g, lvec, addv=PETSc.InsertMode.INSERT_VALUES)
    out = lvec.getArray(readonly=True).reshape(-1, 3).copy()
    dm.restoreLocalVec(lvec)
    g.destroy()
    return out


def owned_sum(dm, local):
    """Owned (n, k) sums over ranks of local (nv, k) vertex values (k <= 3 per pass)."""
    k = local.shape[1]
    out = []
    for c in range(0, k, 3):
        part = np.zeros((local.shape[0], 3))
        part[:, :min(3, k - c)] = local[:, c:c + 3]
        g = fem.local_to_global(dm, part.ravel())
        out.append(g.getArray(readonly=True).reshape(-1, 3)[:, :min(3, k - c)].copy())
        g.destroy()
    return np.hstack(out)


def body_stress(problem, u=None):
    """Stress of the displacement u (a global Vec in x, y, z; default the solution's):
    dict of cell (nc, 6), cell_von_mises, volume, centroid (nc, 3) for the local cells,
    and nodal (n, 6), nodal_von_mises for the owned nodes."""
    u = problem.displacement() if u is None else u
    dm, conn, coords = problem.dm, problem.conn, problem.coords
    ul = local_values(dm, u.getArray(readonly=True).reshape(-1, 3))
    mat = problem.scene["material"]
    lam, mu = fem.lame(mat["young"], mat["poisson"])
    nc = conn.shape[0]
    s, vol = np.zeros((nc, 6)), np.zeros(nc)
    q = problem.quadratic
    per = problem.disc.cell_lame()                  # several bodies: a material per cell
    if q is None:
        for a in range(0, nc, fem.CHUNK):
            c = conn[a:a + fem.CHUNK]
            if per is not None:
                lam, mu = per[0][a:a + fem.CHUNK], per[1][a:a + fem.CHUNK, None, None]
            s[a:a + fem.CHUNK], vol[a:a + fem.CHUNK] = cell_stress(coords[c], ul[c], lam, mu)
    else:                        # cell 8 p + i: the eighth q.octant[8 p + i] of element p
        els, disc = problem.disc.body_element, problem.disc
        m = fem.PRESSURES.get("q2p1" if els and "q2p1" in els else problem.element)
        theta = _projected_theta(coords, ul, q.conn, m) if m else None
        # q2p1's pressure: every element's, or a q2p1 body's (several bodies)
        p1 = np.full(nc, m is not None) if not els else \
            (np.array(els) == "q2p1")[disc.body_of[::8]][np.arange(nc) // 8]
        lin = disc.linear                       # a q1 body's cells beside q2 bodies: q1's
        q1 = np.zeros(nc, bool) if lin is None else lin[np.arange(nc) // 8]
        for o, (rule, _) in enumerate(_OCTANTS):
            for pressure in (False, True):
                cells = np.flatnonzero((q.octant == o) & ~q1 & (p1 == pressure))
                for a in range(0, cells.size, fem.CHUNK // 8):
                    f = cells[a:a + fem.CHUNK // 8]
                    X, U = coords[q.conn[f // 8]], ul[q.conn[f // 8]]
                    if per is not None:
                        lam, mu = per[0][f], per[1][f, None, None]
                    s[f], vol[f] = cell_stress(X, U, lam, mu, rule,
                                               theta[f // 8, o] if pressure else None)
        cells = np.flatnonzero(q1)
        for a in range(0, cells.size, fem.CHUNK):
            f = cells[a:a + fem.CHUNK]
            lam, mu = per[0][f], per[1][f, None, None]
            s[f], vol[f] = cell_stress(coords[conn[f]], ul[conn[f]], lam, mu)
    vals = np.column_stack([s * vol[:, None], vol])               # summed at the nodes
    acc = np.column_stack([np.bincount(conn.ravel(), weights=np.repeat(vals[:, k], 8),
                                       minlength=coords.shape[0]) for k in range(7)])
    tot = owned_sum(dm, acc)
    nodal = tot[:, :6] / np.maximum(tot[:, 6:], 1e-300)
    return {"cell": s, "cell_von_mises": von_mises(s), "volume": vol,
            "centroid": coords[conn].mean(axis=1) if nc else np.zeros((0, 3)),
            "nodal": nodal, "nodal_von_mises": von_mises(nodal)}


def peak(comm, values, where):
    """(max value, its location) over ranks; ties go to the lower rank."""
    i = int(np.argmax(values)) if values.size else -1
    mine = (float(values[i]), [float(c) for c in where[i]]) if i >= 0 else (-np.inf, None)
    return max(comm.allgather(mine), key=lambda p: p[0])


def contact_basis(cs):
    """(m, 3, 3): per owned contact node, row c = the direction in x, y, z of its
    contact-space component c (t1, t2, n), read from the contact set's components (the
    frame's basis off the axes); n's sign is cs.sign's (a contact pair's, per node:
    contact_state); a curved contact pair's bases (cs.bases, fem/pairs_curved.py)."""
    if cs.bases is not None:
        return cs.bases
    if cs.off_axes:
        return np.broadcast_to(basis(cs.normal), (cs.local_size, 3, 3))
    return np.eye(3)[cs.components]


def contact_state(problem, x=None, b=None, gap=None, u=None, slip=None):
    """Owned contact-node fields (module docstring) of the reaction A x - b (default the
    solution's x and load), the displacement u (default x) and the slip of `slip`
    (default the last increment's, else u), all in the loops' basis."""
    cs = problem.cs
    comm = problem.comm.tompi4py()
    x = problem.x if x is None else x
    u = x if u is None else u
    if slip is None:
        slip = problem.last_increment if problem.last_increment is not None else u
    f = res.contact_fields(problem, x, b, gap)
    g, sig_t = res.tractions(f)
    D = contact_basis(cs)
    comps = {id(x): f["u"]}                     # contact components of each Vec, once
    for v in (u, slip):
        if id(v) not in comps:
            comps[id(v)] = res.contact_fields(problem, v)["u"]
    uc, sc = comps[id(u)], comps[id(slip)]
    slip_norm = np.linalg.norm(sc[:, :2], axis=1)
    scale = res.max_displacement(comm, slip)
    pressure = f["l"]
    status = np.where(pressure > 0.0, np.where(slip_norm > 1e-6 * max(scale, 1e-300), 2, 1), 0)
    friction = np.linalg.norm(sig_t, axis=1)
    bound = f["F"] * g
    use = np.zeros_like(friction)
    ok = (status > 0) & (bound > 0.0)
    use[ok] = friction[ok] / bound[ok]
    traction = np.einsum("mc,mcd->md", np.column_stack([sig_t, g * cs.sign]), D)
    return {"coordinates": cs.coordinates, "pressure": pressure, "slip": slip_norm,
            "status": status.astype(np.int32), "traction": traction, "normal_traction": g,
            "friction": friction, "friction_use": use,
            "normal_displacement": uc[:, 2], "tangential_displacement":
            np.linalg.norm(uc[:, :2], axis=1), "w": f["w"], "F": f["F"]}


def resultants(comm, state, normal):
    """Resultant contact force (x, y, z), its normal and tangential parts, and the
    contact, stick and slip areas, summed over ranks (dict, JSON-ready). normal: one
    (3,), or per node (m, 3) (a curved pair's: the normal part is then the sum of the
    nodes' normal forces, the tangential part the resultant of their tangential ones)."""
    normal = np.asarray(normal, dtype=float)
    f = state["traction"] * state["w"][:, None]
    force = comm.allreduce(f.sum(axis=0))
    if normal.ndim == 2:
        fn = np.einsum("ij,ij->i", f, normal)
        N = float(comm.allreduce(fn.sum()))
        tang = comm.allreduce((f - fn[:, None] * normal).sum(axis=0))
    else:
        n = normal / np.linalg.norm(normal)
        N = float(force @ n)
        tang = force - N * n
    areas = np.array([state["w"][state["status"] == k].sum() for k in range(3)])
    areas = comm.allreduce(areas)
    return {"force": [float(c) for c in force], "normal": N,
            "tangential": float(np.linalg.norm(tang)),
            "tangential_force": [float(c) for c in tang],
            "area": {"contact": float(areas[1] + areas[2]), "stick": float(areas[1]),
                     "slip": float(areas[2]), "separated": float(areas[0])}}


def normals(problem):
    """The normal the contact force's normal part is taken along: the problem's one, or
    each contact node's where the contact basis turns from node to node (a curved pair)."""
    cs = problem.cs
    return problem.normal if cs is None or cs.bases is None else _normals(cs)


def _normals(cs, on=slice(None)):
    """Per owned contact node (`on` of them), its normal into the body: the contact
    space's direction 2 times cs.sign (the slave body's side of a pair)."""
    return (cs.bases[:, 2] * np.reshape(cs.sign, (-1, 1)) * np.ones((cs.local_size, 1)))[on]


def pair_results(problem):
    """{part name: resultants} of each contact pair (fem/pairs.py: the master's force on
    the slave body over that pair's slave nodes), or None without pairs."""
    if problem.disc.pair is None:
        return None
    return by_pair(problem.comm.tompi4py(), problem.disc, final(problem)["contact"])


def by_pair(comm, disc, st):
    """{part name: resultants} of the contact state st (contact_state; None: no contact
    nodes here) over each contact pair's slave nodes, or None without pairs."""
    pair, cs = disc.pair, disc.cs
    if pair is None:
        return None
    rstart = disc.coordinates.getOwnershipRange()[0] // 3
    mine = rstart + cs.nodes                                 # global vertex numbers
    out = {}
    for p in pair.pairs:
        on = np.isin(mine, p["slave_ids"])
        sub = {k: st[k][on] for k in ("traction", "w", "status")} if st is not None else \
            {"traction": np.zeros((0, 3)), "w": np.zeros(0), "status": np.zeros(0, int)}
        if p.get("extra") is not None and p["extra"][0].size and st is not None:
            ids, more = p["extra"]           # beside crosspoints: psi_k' (pairs_crosspoints)
            at = np.minimum(np.searchsorted(ids, mine[on]), ids.size - 1)
            sub["w"] = sub["w"] + np.where(ids[at] == mine[on], more[at], 0.0)
        out[p["name"]] = resultants(comm, sub, p["normal"] if p["normals"] is None else
                                    _normals(cs, on))
    return out


_CACHE = weakref.WeakKeyDictionary()


def final(problem):
    """{'body': body_stress, 'contact': contact_state or None} of the solution, computed
    once per solution (summary.json and the files use the same)."""
    key = (id(problem.x), problem.x.stateGet(),
           None if problem.l is None else (id(problem.l), problem.l.stateGet()))
    hit = _CACHE.get(problem)
    if hit is None or hit[0] != key:
        cs = problem.cs
        state = {"body": body_stress(problem),
                 "contact": contact_state(problem) if cs is not None and cs.size else None}
        hit = _CACHE[problem] = (key, state)
    return hit[1]


def summary(problem):
    """summary.json's additions: `contact_result` (resultant, areas; null without
    contact nodes), `contact_result_steps` (per load increment; with contact pairs each
    increment's `pairs`: {part name: resultants}) and `von_mises_max`
    (the largest cell value and the centroid of its cell)."""
    comm = problem.comm.tompi4py()
    st = final(problem)
    body = st["body"]
    value, where = peak(comm, body["cell_von_mises"], body["centroid"])
    out = {"contact_result": (resultants(comm, st["contact"], normals(problem))
                              if st["contact"] is not None else None),
           "von_mises_max": {"value": value if np.isfinite(value) else None,
                             "location": where,
                             "of": "cell mean stress; location: the cell's centroid"}}
    steps = getattr(problem, "increments", None)
    if steps:
        out["contact_result_steps"] = [
            {"load_factor": s["t"], **s["resultant"],
             **({"pairs": s["pairs"]} if s.get("pairs") is not None else {})}
            for s in steps]
    return out
