"""Prototype for the default-solver issue: semismooth Newton on the WHOLE discrete Coulomb
problem (Alart-Curnier), serial, SciPy direct solves. Not the package's solver: it measures
how many Newton steps the whole-problem Newton needs, against the nested loops.

Unknowns: x (the loops' displacement, contact frame: component 3 normal, u_nu = -x3), the
normal pressure l_n and the friction traction l_t (2 per contact node, per unit area). With
R = A x - b the reaction and w the lumped weights, the discrete problem is
    A x - b - C^T (w l) = 0                                 (equilibrium)
    l_n = max(0, a_n),            a_n = l_n - rho (x3 + gap)                   (Signorini)
    l_t = P_{B(F a_n^+)}(z),      z = l_t - rho x_t                            (Coulomb)
the same conditions as the paper's fixed point g = l(g) (the bound F g with g = l). Each step
solves the generalized-Jacobian system (nonsymmetric at slip nodes: the bound depends on
a_n) for all unknowns, then backtracks on the residual norm (the undamped iteration cycles
between two slip sets on the paper's beam). rho = A_33 / w per node.

    python runs/alart_curnier.py --nd 10 --friction 0.3
prints the Newton steps and compares the answer with the package's fast mode at tolerances
1e-11. --smoke: Nd = 2 (tests/test_examples.py).
"""
import argparse
import sys
import time

import petsc4py

petsc4py.init(sys.argv[:1])

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contact.solvers import residuals as res
from contact import scene as scenes  # noqa: E402
from contact.problem import ContactProblem  # noqa: E402
from contact.solvers.solution import Solution
from contact.validation import harness  # noqa: E402

PAPER = f"{harness.ROOT}/runs/paper_beam.yaml"


def scene(nd, friction, **solver):
    sc = scenes.load(PAPER)
    sc["mesh"]["nd"], sc["contact"]["friction"] = nd, friction
    sc["solver"].update(solver)
    return scenes.validate(sc)


class Problem:
    """The discrete problem of a (serial) ContactProblem as SciPy/NumPy arrays."""

    def __init__(self, pr):
        ia, ja, a = pr.A.getValuesCSR()
        self.n = n = pr.A.getSize()[0]
        self.A = sp.csr_matrix((a, ja, ia), shape=(n, n))
        self.b = pr.b.getArray().copy()
        cs = pr.cs
        self.d = [np.asarray(d) for d in cs.dofs]            # tangential 0, 1; normal 2
        self.m = self.d[2].size
        self.w, self.F = cs.local_array(cs.w), cs.local_array(cs.F)
        self.gap = cs.local_array(cs.gap)
        self.rho = np.asarray(self.A.diagonal())[self.d[2]] / self.w

    def state(self, x, ln, lt):
        """Sets, the residual blocks and the slip direction at (x, l_n, l_t)."""
        d0, d1, d2 = self.d
        xn, xt = x[d2] + self.gap, np.c_[x[d0], x[d1]]
        an = ln - self.rho * xn
        active = an > 0
        bound = self.F * np.maximum(an, 0.0)
        z = lt - self.rho[:, None] * xt
        nz = np.linalg.norm(z, axis=1)
        slip = active & (nz > bound)
        stick = active & ~slip
        fc = np.zeros(self.n)
        fc[d2], fc[d0], fc[d1] = self.w * ln, self.w * lt[:, 0], self.w * lt[:, 1]
        r1 = self.A @ x - self.b - fc
        rn = np.where(active, self.rho * xn, ln)
        nv = z / np.where(nz > 0, nz, 1.0)[:, None]
        rt = np.where(stick[:, None], self.rho[:, None] * xt,
                      np.where(slip[:, None], lt - bound[:, None] * nv, lt))
        r = np.concatenate([r1, self.w * rn, self.w * rt[:, 0], self.w * rt[:, 1]])
        return dict(active=active, stick=stick, slip=slip, bound=bound, nz=nz, nv=nv, r=r)

    def jacobian(self, s):
        """The generalized Jacobian of `state`'s residual (rows scaled by w like it)."""
        n, m, w, rho, F = self.n, self.m, self.w, self.rho, self.F
        d0, d1, d2 = self.d
        act, stick, slip = s["active"], s["stick"], s["slip"]
        j = np.arange(m)
        R, C, V = [], [], []

        def add(r, c, v):
            R.append(np.asarray(r))
            C.append(np.asarray(c))
            V.append(np.broadcast_to(np.asarray(v, float), np.shape(r)).copy())

        Ac = self.A.tocoo()
        add(Ac.row, Ac.col, Ac.data)
        for k, dk in enumerate((d0, d1, d2)):               # -C^T w l
            add(dk, n + ((k + 1) % 3) * m + j, -w)
        add(n + j[act], d2[act], (w * rho)[act])             # x3 + gap = 0
        add(n + j[~act], n + j[~act], w[~act])               # l_n = 0
        for k, dk in enumerate((d0, d1)):
            rk = n + (1 + k) * m + j
            add(rk[stick], dk[stick], (w * rho)[stick])      # x_t = 0
            add(rk[~act], rk[~act], w[~act])                 # l_t = 0
        q = np.flatnonzero(slip)
        if q.size:                     # l_t - bound n(z): bound/|z| (I - n n^T) on dz
            c = s["bound"][q] / s["nz"][q]
            nv = s["nv"][q]
            P = np.eye(2)[None] - nv[:, :, None] * nv[:, None, :]
            dl = np.eye(2)[None] - c[:, None, None] * P      # d/d l_t
            dx = (c * rho[q])[:, None, None] * P             # d/d x_t
            for k in range(2):
                rk = n + (1 + k) * m + q
                for l_, dl_ in enumerate((d0, d1)):
                    add(rk, n + (1 + l_) * m + q, w[q] * dl[:, k, l_])
                    add(rk, dl_[q], w[q] * dx[:, k, l_])
                add(rk, n + q, -w[q] * nv[:, k] * F[q])              # - n d bound
                add(rk, d2[q], w[q] * nv[:, k] * F[q] * rho[q])
        N = n + 3 * m
        return sp.csc_matrix((np.concatenate(V), (np.concatenate(R), np.concatenate(C))),
                             shape=(N, N))

    def solve(self, rtol=1e-10, max_it=60, log=print):
        """Newton with backtracking on |r|; returns x, l_n, l_t, steps, linear solves."""
        n, m = self.n, self.m
        x, ln, lt = np.zeros(n), np.zeros(m), np.zeros((m, 2))
        s = self.state(x, ln, lt)
        r0 = nr = np.linalg.norm(s["r"])
        solves = 0
        for it in range(1, max_it + 1):
            dz = spla.spsolve(self.jacobian(s), -s["r"])
            solves += 1
            t = 1.0
            while True:
                xx, lln = x + t * dz[:n], ln + t * dz[n:n + m]
                llt = lt + t * np.c_[dz[n + m:n + 2 * m], dz[n + 2 * m:]]
                s2 = self.state(xx, lln, llt)
                nr2 = np.linalg.norm(s2["r"])
                if nr2 < (1.0 - 1e-4 * t) * nr or t < 1e-3:
                    break
                t *= 0.5
            x, ln, lt, s, nr = xx, lln, llt, s2, nr2
            log(f"  Newton {it:2d}: residual {nr / r0:.2e}, step {t:g}, active "
                f"{s['active'].sum()}, stick {s['stick'].sum()}, slip {s['slip'].sum()}")
            if nr < rtol * r0:
                return x, ln, lt, it, solves
        raise RuntimeError(f"Alart-Curnier Newton did not converge: DIVERGED_MAX_IT at "
                           f"step {max_it} (residual {nr / r0:.2e})")


def compare(nd, friction, log=print):
    """Newton steps of the prototype and of the package (fast mode, tolerances 1e-11), and
    their difference; dict."""
    comm = PETSc.COMM_SELF
    pr = ContactProblem(scene(nd, friction), comm)
    t0 = time.perf_counter()
    x, ln, lt, steps, solves = Problem(pr).solve(log=log)
    t_ac = time.perf_counter() - t0
    X = pr.b.duplicate()
    X.setArray(x)
    proto = Solution(pr.disc, X)                    # the prototype's answer, as a solve's
    proto.l, proto.g = pr.cs.vec(ln), pr.cs.vec(ln)
    resid = res.residuals(proto, X)
    opts = PETSc.Options()
    for k, v in (("solver_mode", "fast"), ("ssn_ksp_rtol", "1e-12")):
        opts.setValue(k, v)
    try:
        ref = ContactProblem(scene(nd, friction, uzawa_rtol=1e-11, fp_rtol=1e-11,
                                   ssn_rtol=1e-13), comm).solve()
    finally:
        for k in ("solver_mode", "ssn_ksp_rtol"):
            opts.delValue(k)
    xr, lr = ref.x.getArray(), ref.cs.local_array(ref.l)
    its = ref.iterations()
    return {"nd": nd, "friction": friction, "steps": steps, "solves": solves,
            "time_s": t_ac, "residuals": resid,
            "u_rel": float(np.abs(x - xr).max() / np.abs(xr).max()),
            "p_rel": float(np.abs(ln - lr).max() / max(np.abs(lr).max(), 1e-300)),
            "package_newton": its["inner_total"], "package_ksp": its["ksp_total"],
            "package_fp": its["fixed_point"]}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nd", type=int, default=6)
    ap.add_argument("--friction", type=float, default=0.3)
    ap.add_argument("--smoke", action="store_true", help="Nd = 2 (tests)")
    args = ap.parse_args(argv)
    nd = 2 if args.smoke else args.nd
    r = compare(nd, args.friction)
    print(f"Nd = {nd}, F = {args.friction:g}: Alart-Curnier Newton {r['steps']} steps "
          f"({r['solves']} linear solves, {r['time_s']:.2f} s, SciPy direct); the package "
          f"(fast, tolerances 1e-11): {r['package_newton']} Newton steps, {r['package_ksp']} "
          f"CG iterations, {r['package_fp']} fixed-point steps")
    print(f"difference: u {r['u_rel']:.1e}, pressure {r['p_rel']:.1e} (relative max); "
          f"residuals " + ", ".join(f"{k} {v:.1e}" for k, v in r["residuals"].items()))
    return r


if __name__ == "__main__":
    main()
