"""Energy and a-posteriori residuals of a computed contact solution.

All residuals use the discrete contact reaction R = A u - b (the nodal force of the
foundation on the body: equilibrium is A u = b + R), so they check the solution
independently of the multipliers the loops carried. At contact node j, weight w_j:
(components in the contact frame of contactset.py: 3 = the normal axis k, nu = -e_k)
  sigma_nu,j  = R_j . nu / w_j = -R_j3 / w_j
  g_j         = -sigma_nu,j = R_j3 / w_j          (contact pressure)
  sigma_tau,j = (R_j1, R_j2) / w_j                 (friction traction)
  u_nu,j      = -u_j3 - gap_j (the normal displacement beyond the gap), u_tau,j = (u_j1, u_j2)
Relative residuals (0 for an exact discrete solution); pressures are scaled by
  max_j |g_j|, or by max_i |b_i| / max_j w_j (about the applied traction) if larger,
  so that a face carrying nothing is not judged by the rounding of its reactions:
  penetration     max_j (u_nu,j)^+ / max_nodes |u|
  complementarity max_j |g_j u_nu,j| / (max_j |g_j| * max_nodes |u|)
  coulomb         max of  max_j (|sigma_tau,j| - F_j g_j^+)^+ / max_j |g_j|   (friction cone)
                  and     max_{j slipping} |sigma_tau,j + F_j g_j u_tau,j/|u_tau,j|| / max_j |g_j|
                  (slip: friction opposes the slip and is at the bound); a node slips when
                  |u_tau,j| > 1e-6 max_nodes |u|.
  tension         max_j (-g_j)^+ / max_j |g_j|   (the foundation cannot pull), folded
                  into complementarity.
The energy is J(u) = 1/2 a(u,u) - b(u) + sum_j F_j g_j w_j |u_tau,j| with the g of the
final solve.
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc


def _max(comm, a, default=0.0):
    v = float(np.max(a)) if np.size(a) else default
    return comm.allreduce(v, op=MPI.MAX)


def max_displacement(comm, x):
    u = x.getArray(readonly=True).reshape(-1, 3)
    return _max(comm, np.linalg.norm(u, axis=1))


def energy(problem, x=None):
    """J(u) = 1/2 <A u, u> - <f, u> + sum_j F_j g_j w_j |u_tau,j| at the full load, u =
    x + u_D: J of the loops' unknown x (1/2 <A x, x> - <b, x>, b = f - A u_D) plus the
    discretisation's energy_shift (1/2 <A u_D, u_D> - <f, u_D>), so that with a prescribed
    displacement it is the body's energy, not one that depends on the lift u_D."""
    x = x if x is not None else problem.x
    Ax = x.duplicate()
    problem.A.mult(x, Ax)
    J = 0.5 * Ax.dot(x) - problem.b.dot(x) + problem.energy_shift
    Ax.destroy()
    cs = problem.cs
    if cs is not None and cs.size and problem.g is not None:
        t1, t2, nrm = cs.vec(), cs.vec(), cs.vec()
        cs.tangential_norm(x, t1, t2, nrm)
        nrm.pointwiseMult(nrm, cs.F)
        nrm.pointwiseMult(nrm, cs.w)
        J += nrm.dot(problem.g)
        for v in (t1, t2, nrm):
            v.destroy()
    return J


def contact_fields(problem, x=None, b=None, gap=None):
    """Owned contact-node arrays: dict of u (m,3), R (m,3), w, F, gap, l (multiplier).
    b, gap: a load increment's (default the problem's)."""
    x = x if x is not None else problem.x
    b = b if b is not None else problem.b
    cs = problem.cs
    R = x.duplicate()
    problem.A.mult(x, R)
    R.axpy(-1.0, b)                              # R = A u - b
    out = {"w": cs.local_array(cs.w), "F": cs.local_array(cs.F),
           "gap": cs.local_array(gap if gap is not None else cs.gap)}
    tmp = cs.vec()
    u, r = np.zeros((cs.local_size, 3)), np.zeros((cs.local_size, 3))
    for c in range(3):
        cs.gather(x, tmp, c)
        u[:, c] = cs.local_array(tmp)
        cs.gather(R, tmp, c)
        r[:, c] = cs.local_array(tmp)
    tmp.destroy()
    R.destroy()
    out.update(u=u, R=r)
    out["l"] = cs.local_array(problem.l) if problem.l is not None else np.zeros(cs.local_size)
    return out


def tractions(f):
    """(g, sigma_tau) of `contact_fields` f: g_j = R_j3 / w_j (the contact pressure) and
    sigma_tau,j = (R_j1, R_j2) / w_j (the friction traction), in the contact frame."""
    return f["R"][:, 2] / f["w"], f["R"][:, :2] / f["w"][:, None]


def residuals(problem, x=None, slip_tol=1e-6, b=None, gap=None):
    """The relative residuals documented above (dict); b, gap: a load increment's."""
    comm = problem.comm.tompi4py()
    x = x if x is not None else problem.x
    umax = max_displacement(comm, x)
    if problem.cs is None or problem.cs.size == 0:
        return {"penetration": 0.0, "complementarity": 0.0, "coulomb": 0.0}
    f = contact_fields(problem, x, b, gap)
    w, F, u = f["w"], f["F"], f["u"]
    g, sig_t = tractions(f)
    un = -u[:, 2] - f["gap"]
    ut = np.linalg.norm(u[:, :2], axis=1)
    gmax = _max(comm, np.abs(g))
    # a pressure scale for when the contact carries (almost) nothing: the largest nodal
    # load spread over the largest contact weight (about the applied traction)
    bmax = (b if b is not None else problem.b).norm(PETSc.NormType.INFINITY)
    p_ref = bmax / max(_max(comm, w), 1e-300)
    gden = max(gmax, p_ref) if max(gmax, p_ref) > 0 else 1.0
    uden = umax if umax > 0 else 1.0
    pen = _max(comm, np.maximum(un, 0.0)) / uden
    comp = _max(comm, np.abs(g * un)) / (gden * uden)
    tension = _max(comm, np.maximum(-g, 0.0)) / gden
    bound = F * np.maximum(g, 0.0)
    cone = _max(comm, np.maximum(np.linalg.norm(sig_t, axis=1) - bound, 0.0)) / gden
    slip = ut > slip_tol * uden
    with np.errstate(invalid="ignore", divide="ignore"):
        mism = np.linalg.norm(sig_t[slip] + bound[slip, None] * u[slip, :2] / ut[slip, None],
                              axis=1)
    mismatch = _max(comm, mism) / gden
    return {"penetration": pen, "complementarity": max(comp, tension),
            "coulomb": max(cone, mismatch)}
