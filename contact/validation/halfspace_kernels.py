"""The half-space's influence coefficients on a uniform grid of square elements (the
Boussinesq and Cerruti point kernels integrated exactly over a constant-traction square),
the quarter-symmetric grid of halfspace_bem.py, and the Hertz values it is started from.
Conventions: halfspace_bem.py's (z into the body, p_z > 0 compressive)."""
import math

import numpy as np

# ------------------------------------------------------------------ influence coefficients
def _xasinh(x, y):
    """x * asinh(y / |x|), continuous (-> 0) at x = 0."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    ax = np.abs(x)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = x * np.arcsinh(y / np.where(ax > 0, ax, 1.0))
    return np.where(ax > 0, v, 0.0)


def _xatan(x, y):
    """x * atan(y / x), continuous (-> 0) at x = 0."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = x * np.arctan(y / np.where(x != 0, x, 1.0))
    return np.where(x != 0, v, 0.0)


def _ylnr(x, y):
    r = np.hypot(x, y)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = y * np.log(np.where(r > 0, r, 1.0))
    return np.where(r > 0, v, 0.0)


_ANTIDERIV = {
    "1": lambda x, y: _xasinh(x, y) + _xasinh(y, x),
    "xx": lambda x, y: _xasinh(y, x),
    "yy": lambda x, y: _xasinh(x, y),
    "xy": lambda x, y: -np.hypot(x, y),
    "x": lambda x, y: _ylnr(x, y) + _xatan(x, y),
    "y": lambda x, y: _ylnr(y, x) + _xatan(y, x),
}

KERNELS = {  # the point kernels themselves (for checks)
    "1": lambda x, y: 1.0 / np.hypot(x, y),
    "xx": lambda x, y: x * x / np.hypot(x, y) ** 3,
    "yy": lambda x, y: y * y / np.hypot(x, y) ** 3,
    "xy": lambda x, y: x * y / np.hypot(x, y) ** 3,
    "x": lambda x, y: x / (x * x + y * y),
    "y": lambda x, y: y / (x * x + y * y),
}


def rect_integrals(X, Y, hx, hy):
    """Integrals of the six kernels over the rectangle |xi|<=hx, |eta|<=hy, at the field point
    (X, Y) relative to its centre: dict kernel-name -> array (broadcast of X, Y)."""
    X = np.asarray(X, float)
    Y = np.asarray(Y, float)
    out = {}
    for name, F in _ANTIDERIV.items():
        s = 0.0
        for sx in (1.0, -1.0):
            for sy in (1.0, -1.0):
                s = s + sx * sy * F(X + sx * hx, Y + sy * hy)
        out[name] = s
    return out


def kernel_point(nu, E=1.0):
    """Coefficients c such that displacement a due to unit point force b is
    sum_k c[(a, b)][k] * kernel_k ; returned as dict (a, b) -> list of (coef, kernel)."""
    G = E / (2.0 * (1.0 + nu))
    cn = (1.0 - nu) / (2.0 * math.pi * G)
    cc = (1.0 - 2.0 * nu) / (4.0 * math.pi * G)
    ct = 1.0 / (2.0 * math.pi * G)
    return {
        ("z", "z"): [(cn, "1")],
        ("x", "z"): [(-cc, "x")], ("y", "z"): [(-cc, "y")],
        ("z", "x"): [(cc, "x")], ("z", "y"): [(cc, "y")],
        ("x", "x"): [(ct * (1.0 - nu), "1"), (ct * nu, "xx")],
        ("y", "y"): [(ct * (1.0 - nu), "1"), (ct * nu, "yy")],
        ("x", "y"): [(ct * nu, "xy")], ("y", "x"): [(ct * nu, "xy")],
    }


def element_influence(X, Y, hx, hy, nu, E=1.0):
    """Displacement component a at (X, Y) (relative to the element centre) due to a unit
    uniform traction component b on the element (half sizes hx, hy): dict (a, b) -> array."""
    I = rect_integrals(X, Y, hx, hy)
    return {ab: sum(c * I[k] for c, k in terms) for ab, terms in kernel_point(nu, E).items()}


def point_displacement(X, Y, nu, E=1.0):
    """Point-load Green's functions (for checks): dict (a, b) -> value at (X, Y)."""
    return {ab: sum(c * KERNELS[k](X, Y) for c, k in terms)
            for ab, terms in kernel_point(nu, E).items()}


# ------------------------------------------------------------------ grid with quarter symmetry
COMP = ("z", "x", "y")


class QuarterGrid:
    """Uniform grid of square elements (side h) on [-L, L]^2 (n x n, n even), reduced to the
    quarter x > 0, y > 0 by symmetry; element centres ((i + 1/2) h, (j + 1/2) h).
    ``keep``: radius within which elements may carry traction (default: all).
    ``coupling``: "full" (exact half-space), or "goodman": the shear tractions' effect on
    u_z dropped (Goodman's approximation; the pressure's effect on u_t is kept), which
    makes the matrix unsymmetric."""

    def __init__(self, n, L, nu, E=1.0, keep=None, coupling="full"):
        if coupling not in ("full", "goodman"):
            raise ValueError("coupling must be 'full' or 'goodman'")
        self.coupling = coupling
        if n % 2:
            raise ValueError("n must be even (quarter symmetry)")
        self.n, self.L, self.nu, self.E = n, float(L), float(nu), float(E)
        self.h = h = 2.0 * L / n
        m = n // 2
        ii, jj = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
        ii, jj = ii.ravel(), jj.ravel()
        x, y = (ii + 0.5) * h, (jj + 0.5) * h
        sel = np.ones(ii.size, bool) if keep is None else np.hypot(x, y) < keep
        self.i, self.j, self.x, self.y = ii[sel], jj[sel], x[sel], y[sel]
        self.r = np.hypot(self.x, self.y)
        self.size = self.x.size
        # kernel tables on integer offsets d in [-m, 2m] (units of h); corners at d +- 1/2,
        # never zero, so no singular evaluation happens here
        d = np.arange(-m, 2 * m + 1)
        DX, DY = np.meshgrid(d * h, d * h, indexing="ij")
        tab = element_influence(DX, DY, h / 2, h / 2, nu, E)
        off = m
        A = {}
        for ab, T in tab.items():
            b = ab[1]
            M = np.zeros((self.size, self.size))
            for sx in (1, -1):
                for sy in (1, -1):
                    # image of source element j at (sx x_j, sy y_j): offset in units of h
                    dxi = self.i[:, None] - (self.i[None, :] if sx > 0 else -self.i[None, :] - 1)
                    dyi = self.j[:, None] - (self.j[None, :] if sy > 0 else -self.j[None, :] - 1)
                    sign = {"z": 1.0, "x": float(sx), "y": float(sy)}[b]
                    M += sign * T[dxi + off, dyi + off]
            A[ab] = M
        if coupling == "goodman":
            A[("z", "x")] = np.zeros_like(A[("z", "x")])
            A[("z", "y")] = np.zeros_like(A[("z", "y")])
        self.A = A

    def full_matrix(self):
        """The 3N x 3N influence matrix, unknown order (p_z, p_x, p_y) blocks."""
        return np.block([[self.A[(a, b)] for b in COMP] for a in COMP])

    def displacement(self, pz, px, py):
        A = self.A
        return {a: A[(a, "z")] @ pz + A[(a, "x")] @ px + A[(a, "y")] @ py for a in COMP}


# ------------------------------------------------------------------ closed forms
def hertz_reference(delta, R, E, nu):
    """Frictionless rigid sphere on a half-space: (a, P, p0) for indentation delta."""
    es = E / (1.0 - nu * nu)
    a = math.sqrt(R * delta)
    P = 4.0 / 3.0 * es * math.sqrt(R) * delta ** 1.5
    return a, P, 3.0 * P / (2.0 * math.pi * a * a)


def beta_dundurs(nu):
    return (1.0 - 2.0 * nu) / (2.0 * (1.0 - nu))


# ------------------------------------------------------------------ incremental solver
