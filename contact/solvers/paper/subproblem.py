"""The Uzawa subproblem  min_x Theta(x) = G(x) + H(x): its formulas, once, in Vec operations.

G(x) = 1/2 <Ax,x> - <b,x> + 1/(2r) sum_j w_j [((l_j + r x_j.nu)^+)^2 - l_j^2]   (smooth)
H(x) = sum_j lambda_j ||x_j,tau||,  lambda_j = F_j g_j w_j                       (prox-able)

With nu = -e_3 in contact space (contactset.py), x_j.nu = -x_j3, and S_j = l_j - r x_j3 is the
penalty's argument:
  grad G(x) = A x - b - w_j S_j^+ e_3,j        (the contact term on the x3 dof of node j)
  prox of sum_j thr_j ||.|| on the tangential pairs: z_tau <- (1 - thr_j / ||z_tau||)^+ z_tau
  L_G = L_A + r max_j w_j  bounds the Lipschitz constant of grad G, with L_A >= lambda_max(A)
        = min(margin x power iteration, ||A||_inf)  (`lipschitz`), or ||A||_inf (`lipschitz_bound`,
        no power iteration).
The change of Theta along a direction d, Theta(x + t d) - Theta(x), is computed term by term,
free of the cancellation of two Theta values (near a minimiser a step changes Theta by far
less than the rounding of Theta itself):
  elastic   t <d, Ax - b> + t^2/2 <d, A d>
  penalty   sum_j w_j/(2r) E_j (E_j + 2 S_j^+),  E = (S + D)^+ - S^+ = max(D + min(S, 0), -S^+),
            D = -r t d_3
  friction  sum_j lambda_j <e_j, 2 a_j + e_j> / (|a_j + e_j| + |a_j|),  a = x_tau, e = t d_tau
Its rounding is about 1e-16 of the sum of the terms' magnitudes (`Change.scale`).

The loops set what changes between calls: the load b (`set_load`, per load increment), the
shifted multiplier l - r gap and the slip bounds lambda (`set_multiplier`, per Uzawa step).
APG (apg.py) and semismooth Newton (ssn.py) only iterate: they call these methods and never
write a formula of Theta. Contact-space NumPy views (`contact_arrays`) serve the Newton
Jacobian; everything else is Vec work (VecScatter to contact space), so it stays on a GPU.
"""
import numpy as np
from petsc4py import PETSc

from contact.fem.contactset import ADD

_EV_LIP = PETSc.Log.Event("Lipschitz estimate")


def power_iteration(apply, template, its):
    """Power-iteration estimate of lambda_max of the SPD operator `apply(v, out)`, from a
    start vector that is the same on any number of ranks."""
    v = template.duplicate()
    lo, hi = v.getOwnershipRange()
    v.setArray(np.sin(0.7 * np.arange(lo, hi) + 0.3) + 1.1)
    w = v.duplicate()
    lam = 0.0
    for _ in range(its):
        v.normalize()
        apply(v, w)
        lam = v.dot(w)
        v, w = w, v
    v.destroy()
    w.destroy()
    return lam


def penalty_increment(S, P, D, c, E, T, zero):
    """E <- (S + c D)^+ - S^+ = max(c D + min(S, 0), -S^+), accurate for small c D (no
    cancellation of two penalties); P = S^+ given, T work (contact Vecs)."""
    T.pointwiseMin(S, zero)
    T.axpy(c, D)
    E.waxpy(-2.0, P, P)                                # -S^+
    E.pointwiseMax(T, E)
    return E


class Change:
    """Theta(x + t d) - Theta(x) as a function of t for one x and direction d (module doc):
    the scalars and contact-space Vecs of x and d are gathered once, each t costs a few
    contact-space operations. `value(t)` returns the change and sets `scale`."""

    def __init__(self, sub, x, d, Ax, Ad):
        cs = sub.cs
        self.sub = sub
        self.g0 = d.dot(Ax) - d.dot(sub.b)             # <d, A x - b>
        self.q = d.dot(Ad)                             # <d, A d>
        self.scale = 0.0
        if not cs.size:
            return
        S, d3, a1, a2, e1, e2, na, E, P, T = sub._change_work()
        sub.penalty_argument(x, S)
        cs.gather(d, d3, 2)
        if sub.lam is not None:
            cs.tangential_norm(x, a1, a2, na)
            cs.gather(d, e1, 0)
            cs.gather(d, e2, 1)
        P.pointwiseMax(S, cs.zero)                     # S^+

    def value(self, t):
        sub, cs = self.sub, self.sub.cs
        el, el2 = t * self.g0, 0.5 * t * t * self.q
        total, scale = el + el2, abs(el) + abs(el2)
        if cs.size:
            S, d3, a1, a2, e1, e2, na, E, P, T = sub._change_work()
            C, U, V = sub._change_extra()
            # penalty: w/(2r) E (E + 2 S^+), D = -r t d3
            penalty_increment(S, P, d3, -sub.r * t, E, T, cs.zero)
            T.waxpy(2.0, P, E)                         # E + 2 S^+
            T.pointwiseMult(T, E)
            T.pointwiseMult(T, cs.w)
            total += T.sum() / (2.0 * sub.r)
            T.abs()
            scale += T.sum() / (2.0 * sub.r)
            if sub.lam is not None:
                # friction: lambda <e, 2a + e> / (|a + e| + |a|), e = t d_tau
                U.waxpy(0.5 * t, e1, a1)               # a1 + e1/2
                C.pointwiseMult(U, e1)
                V.waxpy(0.5 * t, e2, a2)
                V.pointwiseMult(V, e2)
                C.axpy(1.0, V)
                C.scale(2.0 * t)                       # <e, 2a + e>
                U.waxpy(t, e1, a1)
                V.waxpy(t, e2, a2)
                U.pointwiseMult(U, U)
                V.pointwiseMult(V, V)
                U.axpy(1.0, V)
                U.sqrtabs()
                U.axpy(1.0, na)                        # |a + e| + |a|
                U.shift(1e-300)                        # 0/0 -> 0 (the numerator is 0 there)
                C.pointwiseDivide(C, U)
                C.pointwiseMult(C, sub.lam)
                total += C.sum()
                C.abs()
                scale += C.sum()
        self.scale = scale
        return total


class Subproblem:
    """min_x Theta = G + H for the Uzawa multiplier and slip bounds of the current step."""

    def __init__(self, A, b, cs, r):
        self.A, self.b, self.cs, self.r = A, b, cs, float(r)
        if not self.r > 0.0:
            raise ValueError(f"-uzawa_r must be positive, got {r}")
        self.l = None            # the (shifted) multiplier l - r gap, contact Vec
        self.lam = None          # lambda_j = F_j g_j w_j (contact Vec), None: H = 0
        self.L_A = None          # cached lambda_max bound of A (`lipschitz`)
        self.lipschitz_its = 100
        self.lipschitz_margin = 1.1
        self._s = cs.vec()
        self._wmax = cs.w.max()[1] if cs.size else 0.0
        self._work = self._extra = self._bregman = None

    # -- what the loops set ----------------------------------------------------------------
    def set_load(self, b):
        """The load of this solve (the full load, or a load increment's)."""
        self.b = b

    def set_multiplier(self, l, lam=None):
        """l: the shifted multiplier l - r gap; lam: the slip bounds lambda = F g w, or None
        (no friction; also when lam is all zero, so H = 0 and no prox is applied)."""
        self.l = l
        use = lam is not None and self.cs.size and lam.norm(PETSc.NormType.INFINITY) > 0
        self.lam = lam if use else None

    @property
    def has_prox(self):
        return self.lam is not None

    # -- G and its gradient ----------------------------------------------------------------
    def penalty_argument(self, y, S):
        """S <- l - r y3 (= l + r y.nu) at the contact nodes."""
        self.cs.gather(y, S, 2)
        S.aypx(-self.r, self.l)
        return S

    def gradient(self, y, out, Ay=None, S=None):
        """out <- grad G(y) = A y - b - w (l - r y3)^+ on the x3 dofs.

        Ay: A y if known (no MatMult); S: a contact Vec receiving l - r y3."""
        if Ay is None:
            self.A.mult(y, out)
            out.axpy(-1.0, self.b)
        else:
            out.waxpy(-1.0, self.b, Ay)
        cs = self.cs
        if cs.size:
            s = self._s
            cs.gather(y, s, 2)
            s.aypx(-self.r, self.l)                    # l + r u_nu, u_nu = -y3
            if S is not None:
                s.copy(S)
            s.pointwiseMax(s, cs.zero)
            s.pointwiseMult(s, cs.w)
            s.scale(-1.0)
            cs.scatter(s, out, 2, mode=ADD)
        return out

    def value(self, x):
        """Theta(x) (checks and monitors; the loops use `change`, which has no cancellation)."""
        Ax = x.duplicate()
        self.A.mult(x, Ax)
        theta = 0.5 * Ax.dot(x) - self.b.dot(x)
        Ax.destroy()
        cs = self.cs
        if cs.size:
            S, t1, t2, nrm = cs.vec(), cs.vec(), cs.vec(), cs.vec()
            self.penalty_argument(x, S)
            S.pointwiseMax(S, cs.zero)
            S.pointwiseMult(S, S)
            t1.pointwiseMult(self.l, self.l)
            S.axpy(-1.0, t1)
            theta += S.dot(cs.w) / (2.0 * self.r)
            if self.lam is not None:
                cs.tangential_norm(x, t1, t2, nrm)
                theta += nrm.dot(self.lam)
            for v in (S, t1, t2, nrm):
                v.destroy()
        return theta

    # -- H and its prox --------------------------------------------------------------------
    def thresholds(self, alpha, out):
        """out <- alpha lambda: the prox thresholds of a step alpha (a number, or a contact
        Vec of per-node steps)."""
        if isinstance(alpha, PETSc.Vec):
            out.pointwiseMult(alpha, self.lam)
        else:
            self.lam.copy(out)
            out.scale(alpha)
        return out

    def prox(self, z, thr):
        """In place: z <- prox of sum_j thr_j ||z_tau,j|| (the tangential pairs shrunk)."""
        self.cs.shrink_tangential(z, thr)

    def prox_gradient_step(self, y, grad, alpha, out, thr):
        """out <- prox_{alpha H}(y - alpha grad) for a scalar step alpha (thr: work Vec)."""
        out.waxpy(-alpha, grad, y)
        if self.lam is not None:
            self.prox(out, self.thresholds(alpha, thr))
        return out

    # -- Lipschitz bounds ------------------------------------------------------------------
    def lipschitz_A(self):
        """L_A >= lambda_max(A): min(margin * power iteration, ||A||_inf), cached."""
        if self.L_A is None:
            _EV_LIP.begin()
            lam = power_iteration(self.A.mult, self.b, self.lipschitz_its)
            gersh = self.A.norm(PETSc.NormType.INFINITY)
            self.L_A = min(self.lipschitz_margin * lam, gersh) if lam > 0 else gersh
            _EV_LIP.end()
        return self.L_A

    def lipschitz(self):
        """L_A + r max_j w_j: the Lipschitz constant of grad G the paper's step 1/L uses."""
        return self.lipschitz_A() + self.r * self._wmax

    def lipschitz_bound(self):
        """||A||_inf + r max_j w_j >= L_G, without a power iteration."""
        return self.A.norm(PETSc.NormType.INFINITY) + self.r * self._wmax

    def scaled_lipschitz(self):
        """(L_S, diag(A)): L_S >= lambda_max(diag(A)^-1/2 A diag(A)^-1/2), min(margin * power
        iteration, ||.||_inf), for a diagonal metric."""
        _EV_LIP.begin()
        A = self.A
        dA = A.getDiagonal(self.b.duplicate())
        if not dA.min()[1] > 0.0:
            raise ValueError("-apg_metric diagonal needs a positive diagonal of A")
        h = dA.copy()
        h.sqrtabs()
        h.reciprocal()                                 # diag(A)^-1/2
        t = dA.duplicate()

        def apply(v, out):
            t.pointwiseMult(h, v)
            A.mult(t, out)
            out.pointwiseMult(out, h)

        lam = power_iteration(apply, self.b, self.lipschitz_its)
        S = A.duplicate(copy=True)
        S.diagonalScale(h, h)
        gersh = S.norm(PETSc.NormType.INFINITY)
        for o in (S, h, t):
            o.destroy()
        _EV_LIP.end()
        return (min(self.lipschitz_margin * lam, gersh) if lam > 0 else gersh), dA

    # -- changes of Theta and G without cancellation ---------------------------------------
    def change(self, x, d, Ax, Ad):
        """The change of Theta along d from x (`Change`; Ax = A x, Ad = A d given)."""
        return Change(self, x, d, Ax, Ad)

    def penalty_bregman(self, S, dd):
        """sum_j phi_j(y + dd) - phi_j(y) - phi_j'(y) dd for the penalty phi_j of node j, with
        S = l - r y3: w/(2r) [E^2 + 2 S^+ (-(S + D))^+], D = -r dd3 (E as in `Change`)."""
        cs = self.cs
        if not cs.size:
            return 0.0
        if self._bregman is None:
            self._bregman = [cs.vec() for _ in range(5)]
        D, E, P, T, C = self._bregman
        cs.gather(dd, D, 2)
        D.scale(-self.r)
        P.pointwiseMax(S, cs.zero)
        penalty_increment(S, P, D, 1.0, E, T, cs.zero)
        C.waxpy(1.0, S, D)
        C.scale(-1.0)
        C.pointwiseMax(C, cs.zero)                     # (-(S + D))^+
        C.pointwiseMult(C, P)
        E.pointwiseMult(E, E)
        E.axpy(2.0, C)
        return E.dot(cs.w) / (2.0 * self.r)

    def _change_work(self):
        if self._work is None:
            self._work = [self.cs.vec() for _ in range(10)]
        return self._work

    def _change_extra(self):
        if self._extra is None:
            self._extra = [self.cs.vec() for _ in range(3)]
        return self._extra

    # -- contact-space views (the Newton Jacobian) ------------------------------------------
    def contact_arrays(self, x, work):
        """Owned NumPy copies (x1, x2, x3) of x at the contact nodes (work: a contact Vec)."""
        out = []
        for c in range(3):
            self.cs.gather(x, work, c)
            out.append(work.getArray(readonly=True).copy())
        return out
