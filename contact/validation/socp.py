"""Independent reference solver for the discrete 3D frictional contact problem.

Uses the interior-point conic solver Clarabel; it deliberately imports nothing
from the ``contact`` package, so it can be used to cross-check that code.

Discrete Tresca (given friction) problem, u in R^n, dof of node a, comp. c = 3a+c::

    min  J(u) = 1/2 u'Ku - f'u + sum_j w_j s_j ||u_tau,j||_2
    s.t. u[dirichlet] = 0,   u_z,j := u[nrm_dofs[j]] >= 0,

with u_tau,j = (u[tan_dofs[j,0]], u[tan_dofs[j,1]]).  (Rigid foundation z <= 0,
outward normal (0,0,-1), so u_nu = -u_z <= 0.)  KKT conditions on free dofs::

    K u - f - sum_j R_j e_{nrm_j} + sum_j w_j s_j xi_j = 0,
    R_j >= 0, u_z,j >= 0, R_j u_z,j = 0,  xi_j in d||.||(u_tau,j),

so R = (K u - f)[nrm_dofs] is the nodal normal contact force (the multiplier of
u_z >= 0) and the pressure is p_j = R_j / w_j.

Conic form (Clarabel: min 1/2 x'Px + q'x  s.t.  Ax + s = b, s in cone).  With
D = diag(K_ff)^{-1/2} (Jacobi scaling) and a scalar magnitude c, write
u_free = c D z and t_j = c delta_j tau_j (delta_j = max free tangential d).
Dividing J by c^2, the variables x = [z, tau] solve::

    min 1/2 z'(DKD)z - (Df/c)'z + sum_j (w_j s_j delta_j / c) tau_j
    s.t. z_z,j >= 0                                    (NonnegativeConeT(m))
         (tau_j, d_x/delta_j z_x,j, d_y/delta_j z_y,j) in SOC(3)  (s_j > 0)

Clarabel's dual z satisfies Px + q + A'z = 0 with z in the dual cone; since the
nonnegative rows are A = -e, the dual zeta_j >= 0 is the (scaled) multiplier of
z_z,j >= 0 and R_j = zeta_j c / d_z,j.
"""
import warnings

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import clarabel

__all__ = ["solve_tresca", "solve_coulomb"]


#: the largest relative KKT residual an AlmostSolved solution may have (solve_tresca)
ALMOST_KKT = 1e-9


def _settings(tol):
    st = clarabel.DefaultSettings()
    st.verbose = False
    st.tol_gap_abs = st.tol_gap_rel = st.tol_feas = tol
    st.tol_ktratio = max(tol, 1e-12)
    st.max_iter = 500
    return st


def _kkt_residual(K, f, free, nrm, tan, ws, u, R):
    """Relative natural-map KKT residual of (u, R) for the Tresca problem.

    With r = f - K u, kappa = max diag K and lambda_j = r_tau,j (free comps)::

        normal : |r_z + R|,  |R - max(0, R - kappa u_z)|
        tangent: |lambda - P_{B(w s)}(lambda + kappa u_tau)|  (ball projection)
        other free dofs: |r|

    all divided by max(|f|_inf, |R|_inf); 0 iff (u, R) solves the problem.
    """
    r = np.where(free, f - K @ u, 0.0)
    kap = K.diagonal()[free].max()
    ok = free[nrm]
    e = [np.abs(r[nrm] + R)[ok], np.abs(R - np.maximum(0, R - kap * u[nrm]))[ok],
         np.abs(R[~ok])]
    lam = r[tan]
    v = lam + kap * u[tan]
    nv = np.linalg.norm(v, axis=1)
    proj = v * np.minimum(1, ws / np.where(nv > 0, nv, 1))[:, None]
    e.append(np.linalg.norm(lam - proj, axis=1))
    other = free.copy()
    other[nrm] = other[tan.ravel()] = False
    e.append(np.abs(r[other]))
    scale = max(np.abs(f).max(initial=0), np.abs(R).max(initial=0), 1e-300)
    return max(x.max(initial=0.0) for x in e) / scale


def _polish(K, f, free, nrm, tan, ws, u, R):
    """Newton polish of an interior-point solution on its identified active set.

    Active contact: R_j > kappa u_z,j (then u_z,j = 0); stick: |r_tau + kappa
    u_tau| <= w_j s_j (then u_tau,j = 0); on the remaining dofs Newton's method
    minimises the smooth 1/2 u'Ku - f'u + sum_slip w_j s_j |u_tau,j| (Hessian
    K + w_j s_j/|u_tau| (I - nn')).  Returns (u, R) with R = (Ku - f)[nrm] on
    active nodes, or None if Newton fails.
    """
    kap = K.diagonal()[free].max()
    r = np.where(free, f - K @ u, 0.0)
    act = free[nrm] & (R > kap * u[nrm])
    stick = (ws > 0) & (np.linalg.norm(r[tan] + kap * u[tan], axis=1) <= ws)
    slip = (ws > 0) & ~stick
    u = np.where(free, u, 0.0)
    u[nrm[act]] = 0.0
    u[tan[stick]] = 0.0
    keep = free.copy()
    keep[nrm[act]] = keep[tan[stick].ravel()] = False
    ts, wss = tan[slip], ws[slip]
    ii, jj = ts[:, [0, 0, 1, 1]], ts[:, [0, 1, 0, 1]]
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(20):
            ut = u[ts]
            nu = np.linalg.norm(ut, axis=1)
            nn = ut / nu[:, None]
            g = K @ u - f
            g[ts] += wss[:, None] * nn
            blk = (wss / nu)[:, None] * (np.eye(2).ravel() -
                                          nn[:, [0, 0, 1, 1]] * nn[:, [0, 1, 0, 1]])
            H = (K + sp.csr_matrix((blk.ravel(), (ii.ravel(), jj.ravel())),
                                   shape=K.shape))[keep][:, keep]
            try:
                du = spla.spsolve(H.tocsc(), -g[keep])
            except RuntimeError:     # singular reduced Hessian
                return None
            if not np.all(np.isfinite(du)):
                return None
            u[keep] += du
            if np.linalg.norm(du) <= 1e-13 * np.linalg.norm(u):
                break
    return u, np.where(act, (K @ u - f)[nrm], 0.0)


def solve_tresca(K, f, dirichlet, nrm_dofs, tan_dofs, w, s, tol=1e-10):
    """Solve the discrete Tresca problem (see module docstring) with Clarabel.

    Parameters: K (n,n) sparse symmetric PSD stiffness (no BC applied), f (n,),
    dirichlet (int dofs fixed to 0), nrm_dofs (m,), tan_dofs (m,2), w (m,) > 0
    quadrature weights, s (m,) >= 0 slip bounds (pressures), tol solver tolerance.

    The interior-point solution (accurate to ~1e-6 relative in u_tau
    directions) is refined by `_polish` (Newton on the identified active set),
    kept only if it lowers the KKT residual of `_kkt_residual`.

    Returns dict(u=(n,), force=(m,) R_j >= 0, pressure=(m,) R_j/w_j,
    status=str, kkt=relative KKT residual, polished=bool).
    Contact nodes whose normal dof is a Dirichlet dof get force 0; Dirichlet
    tangential dofs are simply absent from the cone (their component is 0).
    Raises RuntimeError unless Clarabel reports ``Solved``.
    """
    K = sp.csr_matrix(K)
    f = np.asarray(f, dtype=float)
    n = f.size
    nrm = np.asarray(nrm_dofs, dtype=int).ravel()
    tan = np.asarray(tan_dofs, dtype=int).reshape(-1, 2)
    m = nrm.size
    w = np.broadcast_to(np.asarray(w, dtype=float), (m,))
    s = np.broadcast_to(np.asarray(s, dtype=float), (m,))

    free_mask = np.ones(n, dtype=bool)
    free_mask[np.asarray(dirichlet, dtype=int).ravel()] = False
    free = np.flatnonzero(free_mask)
    nf = free.size
    if not np.any(f[free]):          # J >= 0 = J(0): u = 0, R = 0 is exact
        z = np.zeros(m)
        return dict(u=np.zeros(n), force=z, pressure=z, status="Solved",
                    kkt=0.0, polished=False)
    gmap = np.full(n, -1)
    gmap[free] = np.arange(nf)

    # Jacobi scaling D and magnitude c so that x = [z, tau] is O(1).
    Kff = K[free][:, free]
    diag = Kff.diagonal()
    d = np.where(diag > 0, 1.0 / np.sqrt(np.where(diag > 0, diag, 1.0)), 1.0)
    Ds = sp.diags(d)
    Kh = (Ds @ Kff @ Ds).tocsc()
    Kh = (0.5 * (Kh + Kh.T)).tocsc()
    gh = d * f[free]

    # nonnegative-cone rows: contact nodes with free normal dof
    cn = np.flatnonzero(gmap[nrm] >= 0)
    zcol = gmap[nrm[cn]]
    # second-order-cone rows: nodes with s_j > 0 and >= 1 free tangential dof
    tcol = gmap[tan]                                       # (m,2), -1 if fixed
    dt = np.where(tcol >= 0, d[np.maximum(tcol, 0)], 0.0)  # (m,2)
    fn = np.flatnonzero((s > 0) & (dt.max(axis=1) > 0))
    mf, mn = fn.size, cn.size
    delta = dt[fn].max(axis=1)

    # A: rows [0, mn) nonneg; rows mn + 3k + (0,1,2) SOC for friction node fn[k]
    k = np.arange(mf)
    tc = tcol[fn]
    ok = tc >= 0
    rows = np.concatenate([np.arange(mn), mn + 3 * k,
                           (mn + 3 * k[:, None] + np.array([1, 2]))[ok]])
    cols = np.concatenate([zcol, nf + k, tc[ok]])
    vals = np.concatenate([-np.ones(mn), -np.ones(mf),
                           -(dt[fn] / delta[:, None])[ok]])
    A = sp.csc_matrix((vals, (rows, cols)), shape=(mn + 3 * mf, nf + mf))
    b = np.zeros(mn + 3 * mf)
    cones = ([clarabel.NonnegativeConeT(mn)] if mn else []) + \
        [clarabel.SecondOrderConeT(3)] * mf
    P = sp.triu(sp.block_diag((Kh, sp.csc_matrix((mf, mf))))).tocsc()

    c = np.abs(gh).max() if nf else 0.0
    c = c if c > 0 else 1.0
    for _ in range(3):   # rescale and re-solve if the solution is far from O(1)
        q = np.concatenate([-gh / c, w[fn] * s[fn] * delta / c])
        sol = clarabel.DefaultSolver(P, q, A, b, cones, _settings(tol)).solve()
        status = str(sol.status)
        if status not in ("Solved", "AlmostSolved"):
            raise RuntimeError(f"clarabel status {status}")
        x = np.asarray(sol.x)
        mag = np.abs(x[:nf]).max() if nf else 1.0
        if mag == 0 or 1e-2 <= mag <= 1e2:
            break
        c *= mag

    u = np.zeros(n)
    u[free] = c * d * x[:nf]
    force = np.zeros(m)
    force[cn] = np.asarray(sol.z)[:mn] * c / d[zcol]

    # friction data seen by polish/KKT: only free tangential components count
    ws = np.zeros(m)
    ws[fn] = w[fn] * s[fn]
    kkt = _kkt_residual(K, f, free_mask, nrm, tan, ws, u, force)
    polished = False
    pol = _polish(K, f, free_mask, nrm, tan, ws, u, force)
    if pol is not None:
        kkt_p = _kkt_residual(K, f, free_mask, nrm, tan, ws, *pol)
        if kkt_p <= kkt:
            (u, force), kkt, polished = pol, kkt_p, True
    # Clarabel 0.11 stops some of these problems at its reduced accuracy (AlmostSolved);
    # such a solution counts only if the KKT residual (after polishing) is a solution's
    if status == "AlmostSolved" and not kkt <= ALMOST_KKT:
        raise RuntimeError(f"clarabel status {status}, relative KKT residual {kkt:.1e} > "
                           f"{ALMOST_KKT:g}")
    return dict(u=u, force=force, pressure=force / w, status=status, kkt=kkt,
                polished=polished)


def solve_coulomb(K, f, dirichlet, nrm_dofs, tan_dofs, w, F, tol=1e-9,
                  max_it=200, g0=None):
    """Discrete Coulomb friction by successive approximations of the slip bound.

    g^0 = 0 (or g0, (m,)); for t = 0, 1, ...: solve Tresca with s = F * g^t, g^{t+1} = its
    pressure; stop when ||g^{t+1} - g^t|| <= tol ||g^{t+1}|| (or both are 0).
    F is scalar or (m,).  Returns dict(u, pressure, force, iterations) at the
    fixed point g = pressure(F g).  Raises RuntimeError after max_it iterations.
    """
    m = np.asarray(nrm_dofs).size
    F = np.broadcast_to(np.asarray(F, dtype=float), (m,))
    g = np.zeros(m) if g0 is None else np.broadcast_to(np.asarray(g0, float), (m,)).copy()
    for it in range(1, max_it + 1):
        res = solve_tresca(K, f, dirichlet, nrm_dofs, tan_dofs, w, F * g)
        gn = res["pressure"]
        if np.linalg.norm(gn - g) <= tol * np.linalg.norm(gn):
            return dict(u=res["u"], pressure=gn, force=res["force"],
                        iterations=it)
        g = gn
    raise RuntimeError(f"solve_coulomb: no convergence in {max_it} iterations")
