"""Admissibility of a scene's discrete problem, checked before any solve.

  prescribed displacement  a nonzero u_D must not reach a contact node (the loops solve for
                           u - u_D, which must vanish there);
  rigid motion             the dirichlet parts and the foundation (its normal direction)
                           must hold every rigid-body motion; motions tangential to the
                           foundation may be left to friction (F > 0): the body is then
                           "friction held", and the statics of a rigid block decide;
  lift-off                 a body held only by the foundation must not be pulled away;
                           with several bodies, one that only its contact pairs hold must
                           have no rigid motion that moves it off them (each node opening,
                           or sliding as friction allows) without the load's negative
                           work: pushed away by a fit, pulled off, or pressed by nothing;
  statics                  a friction-held body's tangential load T must not exceed F_max N
                           at any load step, and the load's resultant must pass through
                           its flat contact face (it tips over otherwise) (-statics_check
                           false skips both).
Each raises SceneError with one line naming the problem.
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact import fem, options
from contact.geometry import basis
from contact.scene import SceneError, ramp_factor

#: a body pushed off its pairs: the rigid motion found opens its contact nodes by this
#: fraction of a unit motion on average (check_pushed_off; rounding opens them by ~1e-16)
OPENING = 1e-2

#: a body's rigid motion counts as free where its contact pairs' normals hold less than
#: this fraction of its motion at the body's held dofs and contact nodes, with a curved
#: pair (the facets' normals at the face's edge, rigid.weakly_held)
WEAK = 1e-2


def check(disc):
    """All checks; returns (friction_held, contact_held): friction_held is None, or (Q,
    frame) of the rigid motions that friction alone must hold (driver.py starts their fixed
    point from a pressure); contact_held: the dirichlet parts alone leave a rigid motion
    free, so the foundation must hold the body (the Newton iteration's first step then
    closes every contact node: from an open gap nothing else would hold it)."""
    check_prescribed_on_contact(disc)
    if disc.bodies is not None:                   # several bodies: each its own check
        return None, check_bodies(disc)
    return check_rigid_motion(disc, options.get("statics_check"))


def check_bodies(disc):
    """SceneError when a body's dirichlet and symmetry parts and its contact pairs (the
    normal direction at each pair's slave nodes, the other body taken as rigid; the
    tangential ones when F > 0) and the foundation leave one of its rigid-body motions
    free. Returns whether a
    body needs the pair to be held (the Newton iteration's first step then closes every
    slave node)."""
    rstart = disc.coordinates.getOwnershipRange()[0]
    rows = np.asarray(disc.clamped_xyz, dtype=np.int64)
    together = fem.free_rigid_modes(disc.coordinates, rows)[0]   # all bodies as one
    on_foundation = together and disc.foundation_points is not None
    if on_foundation:                             # beside pairs (discretisation.py)
        n = disc.foundation_normal
        together, Q, _ = fem.free_rigid_modes(disc.coordinates, rows, disc.foundation_points,
                                              n)
        if together and fem.tangential_modes(Q, n) and disc.cs.has_friction:
            together = []                         # (friction may hold them: F > 0)
    if together:
        raise SceneError(f"the bodies together are held by nothing in {', '.join(together)} "
                         f"(their dirichlet and symmetry parts"
                         + (", the foundation the normal direction" if on_foundation else "")
                         + "): no equilibrium; support one")
    pair = {b for _, *both in disc.pair_bodies or () for b in both} | disc.foundation_bodies
    needs_pair = bool(on_foundation)
    cs = disc.cs                                  # each contact node's normal (pairs: +-e_k)
    normals = np.asarray(disc.normal, dtype=float) if cs is None or cs.off_axes else \
        np.eye(3)[cs.components[:, 2]] if cs.bases is None else cs.bases[:, 2]
    ks = sorted(set().union(*disc.comm.tompi4py().allgather(
        set() if cs is None or cs.off_axes else set(cs.components[:, 2].tolist()))))
    # (a curved pair's nodes, each its own normal: a motion they leave free is tangential)
    tangential = lambda Q: cs.bases is not None or all(  # noqa: E731
        fem.tangential_modes(Q, n) for n in ([disc.normal] if not ks else np.eye(3)[ks]))
    gid = rstart // 3 + (cs.nodes if cs is not None else np.zeros(0, dtype=np.intp))
    for i, (name, mask) in enumerate(zip(disc.bodies, disc.body_masks())):
        m = mask.getArray(readonly=True).copy()
        mine = rows[m[rows - rstart] > 0.5] if rows.size else rows
        # its contact nodes: its own, and the slave nodes of the pairs it is the master of
        near = m[3 * (gid - rstart // 3)] > 0.5
        for (_, _, master), p in zip(disc.pair_bodies or (), getattr(disc.pair, "pairs", ())):
            if master == name:
                near |= np.isin(gid, p["slave_ids"])
        mask.destroy()
        own = fem.free_rigid_modes(disc.coordinates, mine)
        if not own[0]:
            continue
        if name not in pair:
            raise SceneError(f"body {name!r} is held by nothing in {', '.join(own[0])}: "
                             f"add a dirichlet or symmetry part, or a contact pair")
        needs_pair = True
        args = (disc.coordinates, mine, cs.coordinates[near],
                normals if normals.ndim == 1 else normals[near])
        free, Q, _ = fem.free_rigid_modes(*args)
        facets = False
        if cs.bases is not None:                  # a curved pair: what its facets hold
            weak = fem.free_rigid_modes(*args, weak=WEAK)
            facets = weak[1].shape[1] > Q.shape[1]
            free, Q = weak[:2]
        if free and not (tangential(Q) and cs.has_friction):
            raise SceneError(f"body {name!r}: its dirichlet and symmetry parts and the contact "
                             f"pair leave rigid-body motion free ({', '.join(free)}; the "
                             f"pair holds the normal direction"
                             + (", friction could hold the others, but F = 0)"
                                if tangential(Q) else ")")
                             + (" (a curved face's facets hold it at the face's edges only, "
                                f"under {WEAK:.0%} of its motion there)" if facets else "")
                             + ": no unique solution")
        signed = np.broadcast_to(normals, (len(gid), 3)) * np.broadcast_to(
            np.asarray(cs.sign, dtype=float), (len(gid),))[:, None]
        role = np.where(m[3 * (gid - rstart // 3)] > 0.5, 1.0, -1.0)     # slave, master
        check_pushed_off(disc, name, np.flatnonzero(m[0::3] > 0.5), own,
                         cs.coordinates[near], (role[:, None] * signed)[near],
                         cs.local_array(cs.F)[near])
    return needs_pair


def check_pushed_off(disc, name, nodes, own, points, opening, friction):
    """SceneError when a body that only its contact pairs hold (own: free_rigid_modes of
    its dirichlet and symmetry parts alone, their motions Q0) can move off them: a rigid
    motion q in span Q0 against which the contact forces do no work at any node (opening
    o_j = n_j . u_j(q) >= F_j |s_j|, s_j its sliding: the polar cone of Coulomb's, the
    octagon inside the disc; n_j the normal into the slave body, turned where the body is
    the master, the other bodies held still) and which opens some node, while the load
    does no negative work on it at some load step. Then the pairs can only push the body
    away (an overlap, a fit) or nothing presses it on them: no equilibrium, or none unique
    (strict compatibility: Fichera; by Farkas the dual of the contact forces' balance of
    the load). A linear programme over q (|q|_1 <= 1) maximising the opening; refused
    where it opens the nodes by OPENING of a unit motion on average."""
    from scipy.optimize import linprog
    names, Q0, frame = own
    if not names:
        return
    mpi = disc.comm.tompi4py()
    u = fem.rigid_modes(points, *frame) @ Q0                       # (p, 3, k)
    keep = np.linalg.norm(opening, axis=1) > 0.5                 # (a node of no normal: 0)
    u, opening, friction = u[keep], opening[keep], friction[keep]
    T = basis(opening)                                            # (p, 3, 3): t1, t2, n
    o = np.einsum("pc,pck->pk", opening, u)
    s1, s2 = (np.einsum("pc,pck->pk", T[:, i], u) for i in (0, 1))
    on = friction > 0.0                   # F (s . e_k) <= o cos(pi / 8): the octagon
    f, s1, s2, oo = friction[on, None] / np.cos(np.pi / 8), s1[on], s2[on], o[on]
    slid = [f * (np.cos(t) * s1 + np.sin(t) * s2) - oo for t in np.arange(8) * np.pi / 4]
    A = np.vstack(mpi.allgather(np.vstack([-o] + slid)))           # A q <= 0
    O = np.vstack(mpi.allgather(o))
    xyz = disc.coordinates.getArray(readonly=True).reshape(-1, 3)[nodes]
    M = fem.rigid_modes(xyz, *frame) @ Q0
    works = []
    for ramp, mine, _ in disc.load_groups:      # the load's work on each motion, per group
        f = disc.xyz_load(ramp, mine)
        works.append(mpi.allreduce(np.einsum(
            "pc,pck->k", f.getArray(readonly=True).reshape(-1, 3)[nodes], M)))
        f.destroy()
    steps = int(disc.scene.get("loading", {}).get("steps", 1))
    found = None
    if mpi.rank == 0 and O.shape[0]:
        for k in range(1, steps + 1):
            w = sum(ramp_factor(r, k / steps) * wg
                    for (r, _, _), wg in zip(disc.load_groups, works))
            # q = q+ - q-, |q|_1 <= 1: the vertices name few motions
            c = O.sum(axis=0)
            lp = linprog(np.r_[-c, c], A_ub=np.vstack([np.hstack([A, -A]), np.r_[-w, w],
                                                       np.ones(2 * len(c))]),
                         b_ub=np.r_[np.zeros(A.shape[0] + 1), 1.0], bounds=(0.0, None),
                         method="highs")
            if lp.status == 0 and -lp.fun > OPENING * O.shape[0]:
                q = np.abs(Q0 @ (lp.x[:len(c)] - lp.x[len(c):]))
                found = (k, [fem.RIGID_MODES[j] for j in np.flatnonzero(q > 0.5 * q.max())])
                break
    found = mpi.bcast(found)
    if found is not None:
        k, which = found
        at = f" at load step {k} of {steps}" if steps > 1 else ""
        raise SceneError(f"body {name!r}: only its contact pairs hold it, and a rigid motion "
                         f"({', '.join(which)}) moves it off them (every node opens, or "
                         f"slides as friction allows) without the load{at} doing negative "
                         f"work: the pairs cannot hold it there (no equilibrium, or none "
                         f"unique); support it, or load it onto the pairs")


def check_prescribed_on_contact(disc):
    """SceneError when a nonzero prescribed displacement touches a contact node (the
    loops solve for u - u_D, which must vanish there)."""
    if disc.u_D is None:
        return
    cs, tmp, worst = disc.cs, disc.cs.vec(), 0.0
    for c in range(3):
        cs.gather(disc.u_D, tmp, c)
        worst = max(worst, tmp.norm(PETSc.NormType.INFINITY))
    tmp.destroy()
    if worst > 0.0:
        raise SceneError("a nonzero prescribed displacement reaches a contact node; "
                         "prescribe it away from the contact part (or press through "
                         "contact.gap)")


def check_rigid_motion(disc, statics=True):
    """SceneError when the dirichlet parts and the foundation leave a rigid-body motion
    free, or when only the foundation holds the body and the load pulls it away.

    Motions tangential to the foundation (translations along it, rotation about its
    normal) may be left to friction (F > 0): the body is then `friction_held`, and the
    statics of a rigid block decide (`check_friction_statics`). Returns (friction_held,
    contact_held) as `check`."""
    held = None
    cpts = disc.cs.coordinates if disc.cs is not None else None
    n = disc.normal
    free, Q, frame = fem.free_rigid_modes(disc.coordinates, disc.clamped_xyz, cpts, n)
    # the motions the dirichlet parts alone leave free (the foundation aside)
    unheld = fem.free_rigid_modes(disc.coordinates, disc.clamped_xyz) if cpts is not None \
        else None
    if free:
        tangential = cpts is not None and fem.tangential_modes(Q, n)
        if tangential and disc.cs.has_friction:
            held = (Q, frame)
            if statics:                                  # (-statics_check)
                check_friction_statics(disc, Q, unheld[1])
                check_tipping(disc, *unheld[1:])
        else:
            why = ""
            if cpts is not None:
                why = " (the foundation holds only the normal direction" + (
                    "; friction could hold the tangential ones, but F = 0)"
                    if tangential else ")")
            raise SceneError("the dirichlet parts leave rigid-body motion free ("
                             + ", ".join(free) + f"){why}: no unique solution; clamp "
                             "more components or parts")
    if cpts is None:
        return held, False
    free, Q, frame = unheld
    if free:
        b = disc.to_xyz(disc.b)
        lifts = fem.load_lifts_off(disc.coordinates, b, Q, frame, cpts, n)
        if b is not disc.b:
            b.destroy()
        if lifts:
            raise SceneError("only the foundation holds the body (" + ", ".join(free) +
                             " free otherwise) and the load pulls it away: no "
                             "equilibrium")
    return held, bool(free)


def check_friction_statics(disc, Q, Q0):
    """Statics of a rigid block, at every load step: where nothing but the foundation
    holds the body (normal translation in span Q0, the motions the dirichlet parts
    leave free), the tangential load resultant
    T along the free translations (those in span Q, the motions friction must hold)
    must not exceed F_max N, N the normal load pressing the body on the foundation;
    otherwise the body slides (no static equilibrium). Necessary, not sufficient
    (moments about the normal are left to the solver). -statics_check 0 skips it (check)."""
    n = disc.normal
    e_n = np.r_[n, 0.0, 0.0, 0.0]
    if np.linalg.norm(e_n - Q0 @ (Q0.T @ e_n)) > 1e-6:
        return                               # a dirichlet part takes normal load: N unknown
    D = fem.free_translations(Q)             # (3, m): orthonormal free directions
    if D.shape[1] == 0:
        return
    fmax = disc.cs.F.max()[1]
    for at, R, _ in step_loads(disc):
        N, T = -float(R @ n), float(np.linalg.norm(D.T @ R))
        if T > fmax * max(N, 0.0) * (1.0 + 1e-9) + 1e-14 * np.abs(R).max():
            raise SceneError(
                f"the tangential load T = {T:.6g}{at} exceeds the friction limit F N = "
                f"{fmax:g} x {N:.6g} = {fmax * N:.6g}: the body slides on the "
                f"foundation (statics of a rigid block; no static equilibrium)")


def step_loads(disc, p0=None):
    """The load's resultant force R and (with p0) moment M about p0 at every load step
    (the ramps of the load groups at t = k / steps): yields (at, R, M), `at` the step's
    words for a message ("" for a static load)."""
    mpi = disc.comm.tompi4py()
    xyz = None if p0 is None else \
        disc.coordinates.getArray(readonly=True).reshape(-1, 3) - p0
    sums = []
    for _, _, bg in disc.load_groups:
        f = disc.xyz_rows(bg)
        sums.append((mpi.allreduce(f.sum(axis=0)),
                     None if xyz is None else mpi.allreduce(np.cross(xyz, f).sum(axis=0))))
    steps = int(disc.scene.get("loading", {}).get("steps", 1))
    for k in range(1, steps + 1):
        t = k / steps
        w = [ramp_factor(r, t) for r, _, _ in disc.load_groups]
        R = sum(wi * F for wi, (F, _) in zip(w, sums))
        M = None if xyz is None else sum(wi * Mg for wi, (_, Mg) in zip(w, sums))
        yield (f" at load step {k} of {steps} (t = {t:g})" if steps > 1 else ""), R, M


def check_tipping(disc, Q0, frame):
    """Statics of a rigid block about the edges of its contact face, at every load step:
    where nothing but the foundation holds the body's normal translation and its rotations
    about the two tangential axes (span Q0), the foundation's normal forces (>= 0) must
    balance the load's moment, so the load's centre of pressure c = -(n x M) / N (M: the
    load's moment about a point of the face, N: its normal force) must lie in the convex
    hull of the contact face; otherwise the body tips over (no static equilibrium; the
    rigid rotation about the edge is free and the Newton iteration would follow it).
    Checked for a flat face only (friction's moments vanish there); necessary, not
    sufficient. SceneError names the step and the distance outside."""
    from scipy.spatial import ConvexHull, QhullError
    mpi = disc.comm.tompi4py()
    n = np.asarray(disc.normal, dtype=float)
    pts = disc.cs.coordinates
    cnt = mpi.allreduce(pts.shape[0])
    if cnt < 3:
        return
    p0 = mpi.allreduce(pts.sum(axis=0)) / cnt
    x0, h = frame
    t1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    # the motions that must be free: the normal translation, the tangential rotations
    # about p0 (rigid_modes' coordinates: translation, rotation x h about x0)
    need = [np.r_[n, 0.0, 0.0, 0.0]] + [np.r_[np.cross(t, x0 - p0), h * t] for t in (t1, t2)]
    for v in need:
        if np.linalg.norm(v - Q0 @ (Q0.T @ v)) > 1e-6 * np.linalg.norm(v):
            return                           # a dirichlet part holds it
    d = pts - p0
    off = mpi.allreduce(np.abs(d @ n).max(initial=0.0), op=MPI.MAX)
    if off > 1e-8 * h:
        return                               # not a flat face on the foundation's plane
    local = np.c_[d @ t1, d @ t2]
    if local.shape[0] >= 3:
        try:
            local = local[ConvexHull(local).vertices]
        except QhullError:
            pass                             # collinear: all of them
    face = np.vstack(mpi.allgather(local))
    try:
        hull = ConvexHull(face)
    except QhullError:
        return                               # a face of no area (a line): not checked
    for at, R, M in step_loads(disc, p0):
        N = -float(R @ n)
        if N <= 1e-14 * max(np.abs(R).max(), 1e-300):
            continue                         # not pressed: the lift-off check's
        c = -np.cross(n, M) / N
        cp = np.array([c @ t1, c @ t2])
        out = float(np.max(hull.equations[:, :2] @ cp + hull.equations[:, 2]))
        if out > 1e-9 * h:
            xyz_c = p0 + cp[0] * t1 + cp[1] * t2
            raise SceneError(
                f"the load's resultant{at} meets the foundation at "
                f"({', '.join(f'{v:.6g}' for v in xyz_c)}), {out:.3g} outside the contact "
                f"face: the body tips over (statics of a rigid block; no static "
                f"equilibrium)")
