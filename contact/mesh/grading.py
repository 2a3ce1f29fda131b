"""Graded box meshes: the box's vertices on a per-axis monotone map of the lattice.

Scene (mesh.type box): `grading: {x: {bump: 0.08}, z: {progression: 4.0}}`, one kind per
axis (axes left out stay uniform). Along an axis with lower a and upper b a lattice point
a + t (b - a), t in [0, 1], is placed at a + phi(t) (b - a), phi: [0, 1] -> [0, 1]
increasing, phi(0) = 0, phi(1) = 1. The map is applied to every level of the hierarchy
(hierarchy.py): level j's vertices are phi of level j's uniform lattice, so the family is
one graded family, refined uniformly in t (h -> 0 everywhere), and its cells stay
axis-aligned boxes (a tensor product of 1D maps).

    bump c         (c > 0) the cell size, as a density of t, is (b - a) / phi'(t) with
                   1 / phi' a parabola in t symmetric about 1/2: cells at both ends c
                   times the size of those in the middle (c < 1: finer at the ends, c > 1:
                   coarser, 1: uniform). With s = sqrt|1 - c|:
                     c < 1: phi(t) = 1/2 + tanh((2t - 1) atanh(s)) / (2 s)
                     c > 1: phi(t) = 1/2 + tan((2t - 1) atan(s)) / (2 s)
                   gmsh's "Transfinite Curve {..} = n Using Bump c" is this size function
                   (its meshGEdge.cpp: size -a (t - 1/2)^2 + b, b = -a / (4 (c - 1))):
                   its nodes are phi(i / n) up to gmsh's numerical integration of the
                   density (1e-3 of the cell size in tests/mesh/test_grading.py).
    progression r  (r > 0) cell sizes growing geometrically along the axis, by r from the
                   lower end to the upper one (the size ratio of the ends, phi'(1) /
                   phi'(0) = r): phi(t) = (r^t - 1) / (r - 1). On n cells consecutive
                   cells differ by r^(1/n): gmsh's "Using Progression q" on n cells is
                   r = q^n, exactly (its nodes (q^i - 1) / (q^n - 1)).
    points [p_0, .., p_K]  phi(k / K) = p_k, linear in between: increasing from 0 to 1;
                   what `auto` writes (equidistribute; scene_grading.py).
    auto           (scene_grading.py, contact/adapt.py) the run chooses the axis's points
                   from the error indicator of a solved coarser mesh (equidistribute).

Ranges (scene_grading.py): 1e-3 <= c, r <= 1e3; points' steps at least 1e-6. The q2
element's nodes are the vertices of the next level, phi of its lattice: the images of the element's reference
nodes, and the element is isoparametric (fem/element.py), so its geometry is the one the
nodes give (an edge's middle node is not the edge's midpoint: the element map is the
quadratic interpolant of phi, positive where phi' varies little over an element).
"""
import numpy as np

from mpi4py import MPI

from contact.mesh.plex import HEX_REF, MeshError, boundary_faces

AXES = ("x", "y", "z")
KINDS = ("bump", "progression", "points")
#: equidistribute's safeguards: the largest ratio of cell sizes along an axis, and of
#: neighbouring slabs' sizes
MAX_RATIO, GROWTH = 30.0, 1.5
#: the smallest local order equidistribute trusts (an edge singularity r^(1/2): 1/2)
B_MIN = 0.25


def bump(t, c):
    """gmsh's Bump c as a map of [0, 1] (module docstring)."""
    t = np.asarray(t, dtype=float)
    if c == 1.0:
        return t.copy()
    s = np.sqrt(abs(1.0 - c))
    u = 2.0 * t - 1.0
    v = np.tanh(u * np.arctanh(s)) if c < 1.0 else np.tan(u * np.arctan(s))
    return _ends(t, 0.5 + v / (2.0 * s))


def progression(t, r):
    """Sizes growing by r from t = 0 to t = 1 (module docstring)."""
    t = np.asarray(t, dtype=float)
    if r == 1.0:
        return t.copy()
    return _ends(t, np.expm1(t * np.log(r)) / np.expm1(np.log(r)))


def _ends(t, y):
    """y with the ends exact (boundary planes are found by their coordinates)."""
    return np.where(t <= 0.0, 0.0, np.where(t >= 1.0, 1.0, np.clip(y, 0.0, 1.0)))


def points(t, values):
    """phi through (k / K, values[k]), k = 0 .. K, linear in between (a grading written out
    by equidistribute, or by hand): values increase from 0 to 1."""
    v = np.asarray(values, dtype=float)
    return _ends(np.asarray(t, dtype=float),
                 np.interp(t, np.linspace(0.0, 1.0, v.size), v))


MAPS = {"bump": bump, "progression": progression, "points": points}


def equidistribute(edges, errors, order, cells, coarse=None, max_ratio=MAX_RATIO,
                   growth=GROWTH, samples=4):
    """A grading of one axis from a solved mesh's error along it: `points` values (phi at
    t = k / K, K = samples len(errors)) placing `cells` cells where they reduce the error
    most.

    edges (m + 1,): the solved mesh's cell planes along the axis (its slabs j, widths h_j);
    errors (m,): the squared error indicator summed over each slab's cells, E_j; coarse
    (m / 2,) or None: the same sums on the mesh twice as coarse (slab pairs 2J, 2J + 1).
    Model: in slab j the error per unit length is k_j h^(2 b_j), b_j its local order: from
    the two meshes where coarse is given (E(h) / E(2h) = 4^-b over groups of 4 fine and
    2 coarse slabs, the cells of the level below both: each level's change has its own
    pattern inside the cells it refined; b in [B_MIN, order]), else `order` (the element's order in the energy norm: 1 for q1, 2 for q2). Minimising the
    total error with `cells` cells (the number of cells along the axis of the mesh to
    build) gives h_j = (lam / (2 b_j k_j))^(1 / (2 b_j + 1)), lam such that
    sum (h_j-width / h_j) = cells (equidistribution of the error's derivative; e.g. Huang &
    Russell, Adaptive Moving Mesh Methods, 2011, ch. 2): a slab whose error falls slowly
    (a singular edge) gets more of the cells the finer the mesh to build. Safeguards: no
    cell larger than max_ratio times the smallest (a slab with no error is not emptied),
    neighbouring slabs' cells within `growth` (the q2 element's middle node stays inside
    the middle half of its edges). phi is the inverse of the cumulative cell density,
    sampled at t = k / K (`samples` points a slab: linear between them, phi is its
    inverse to ~1 / samples^2 of a slab). Errors all zero: uniform."""
    X = np.asarray(edges, dtype=float)
    h, E = np.diff(X), np.maximum(np.asarray(errors, dtype=float), 0.0)
    m = E.size
    K = samples * m
    if not E.any():
        return np.linspace(0.0, 1.0, K + 1)
    b = np.full(m, float(order))
    if coarse is not None:
        # compared over the cells of the level below the coarse one (4 fine slabs, 2
        # coarse): each level's change has its own pattern within the cells it refined
        g = 4 if m % 4 == 0 else 2
        fine = E.reshape(-1, g).sum(axis=1)
        cs = np.asarray(coarse, dtype=float).reshape(-1, g // 2).sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = 0.5 * np.log2(cs / fine)
        r = np.clip(np.nan_to_num(r, nan=order, posinf=order, neginf=B_MIN), B_MIN, order)
        b = np.repeat(r, g)
    tiny = E.max() * 1e-12
    k = (np.maximum(E, tiny) / h) / h ** (2 * b)          # error per length / h^(2b)

    def sizes(log_lam):
        return np.exp((log_lam - np.log(2 * b * k)) / (2 * b + 1))

    lo_, hi_ = -200.0, 200.0                              # sum(h / size) falls with lam
    for _ in range(200):
        mid = 0.5 * (lo_ + hi_)
        lo_, hi_ = (mid, hi_) if (h / sizes(mid)).sum() > cells else (lo_, mid)
    w = 1.0 / sizes(0.5 * (lo_ + hi_))
    w = np.maximum(w, w.max() / max_ratio)
    j = np.arange(m)
    w = (w[None, :] / growth ** np.abs(j[:, None] - j[None, :])).max(axis=1)
    T = np.concatenate([[0.0], np.cumsum(w * h)])
    phi = (np.interp(np.linspace(0.0, 1.0, K + 1), T / T[-1], X) - X[0]) / (X[-1] - X[0])
    phi[0], phi[-1] = 0.0, 1.0
    return phi


def graded(coords, grading, lower, upper):
    """coords (n, 3) of the box [lower, upper] placed by `grading` (the scene's
    mesh.grading, validated): a new array; axes not graded are copied as they are."""
    out = np.array(coords, dtype=float, copy=True)
    if grading == "auto" or "auto" in grading.values():
        raise MeshError("mesh.grading auto is chosen by the command line's run (contact/"
                        "adapt.py: a pilot's error indicator), not by the mesh")
    for axis, spec in (grading or {}).items():
        (kind, value), = spec.items()
        i, lo, hi = AXES.index(axis), float(lower[AXES.index(axis)]), float(upper[AXES.index(axis)])
        t = (out[:, i] - lo) / (hi - lo)
        x = lo + MAPS[kind](t, value) * (hi - lo)
        out[:, i] = np.where(t >= 1.0, hi, x)
    return out


def place(level, cells, lower, upper, grading=None):
    """The level's vertices on the box's lattice, lower + i (upper - lower) / n as
    DMPlexCreateBoxMesh writes them (level.reference), then graded (level.coords and the
    DM's coordinates): a refined vertex is a mean of its parent's (an edge's midpoint,
    ...), which rounds differently from vertex to vertex along one grid line; snapped, the
    refined box is the box built whole, to the bit (canonical orders, which sort by
    coordinates, rely on it). The refinement and the search for a fine vertex's place in
    its parent (hierarchy.prolongation, QuadraticCells) use level.reference."""
    lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    h = (hi - lo) / np.asarray(cells, dtype=float)
    x = level.reference
    snapped = lo + h * np.rint((x - lo) / h)
    if x.size and np.abs(snapped - x).max() > 1e-9 * np.abs(h).min():
        raise MeshError("a refined vertex is off the box's lattice")
    level.reference = snapped
    level.coords = graded(snapped, grading, lo, hi) if grading else snapped
    v = level.dm.getCoordinatesLocal()
    if grading:           # a Vec of its own: DMRefine's mesh shares the one it had
        v, level.lattice = v.duplicate(), None       # (and no box of identical cells)
    v.setArray(level.coords.ravel())
    level.dm.setCoordinatesLocal(v)                  # drops the global copy, if one was made


def lattice_planes(coords, vertices, comm):
    """A gmsh or file mesh graded (mesh.grading): per axis the planes (sorted, every
    rank's) of its vertices `coords` (local, (n, 3)), which must be the whole lattice of
    those planes (`vertices`, the global count, their product: a tensor-product hexahedral
    mesh of a box, as gmsh's extruded layers and transfinite volumes give); MeshError
    otherwise, naming the counts (the hierarchy then takes box_planes)."""
    mpi = comm.tompi4py()
    planes = []
    for a in range(3):
        x = np.unique(np.concatenate(mpi.allgather(np.unique(coords[:, a]))))
        span = x[-1] - x[0] if x.size else 0.0
        planes.append(x[np.concatenate([[True], np.diff(x) > 1e-9 * span])])
    counts = [p.size for p in planes]
    if int(np.prod(counts)) != vertices:
        raise MeshError(f"mesh.grading on a gmsh or file mesh needs a tensor-product "
                        f"hexahedral mesh of a box (its vertices on a lattice of planes); "
                        f"this one has {vertices} vertices on {' x '.join(map(str, counts))} "
                        f"planes")
    return planes


def box_planes(level, comm):
    """A gmsh or file mesh off any lattice graded (mesh.grading): per axis its extent's two
    planes, [lower, upper], so that place_lattice maps it as one slab (a per-axis
    coordinate map of the box: cells stay whole, their vertices move), where the mesh is a
    box: the cell faces on the six planes of its bounding box cover them (their areas
    summed over ranks, to 1e-9); MeshError otherwise (a curved face, a hole)."""
    mpi, x, conn = comm.tompi4py(), level.reference, level.conn
    lo, hi = np.empty(3), np.empty(3)
    mpi.Allreduce(x.min(axis=0) if x.size else np.full(3, np.inf), lo, op=MPI.MIN)
    mpi.Allreduce(x.max(axis=0) if x.size else np.full(3, -np.inf), hi, op=MPI.MAX)
    tol = 1e-9 * float(np.max(hi - lo))
    for a in range(3):
        side = np.prod(np.delete(hi - lo, a))
        for v in (lo[a], hi[a]):
            f = x[boundary_faces(conn, x, a, v, tol)]
            c = np.cross(f[:, 2] - f[:, 0], f[:, 3] - f[:, 1])
            area = mpi.allreduce(0.5 * float(np.linalg.norm(c, axis=1).sum()))
            if abs(area - side) > 1e-9 * side:
                raise MeshError(f"mesh.grading on a gmsh or file mesh needs a hexahedral mesh "
                                f"of a box (a tensor-product one, or any: a per-axis map); "
                                f"this one's faces on its bounding box's plane {AXES[a]} = "
                                f"{v:g} cover {area:.6g} of that side's {side:.6g}")
    return [np.array([lo[a], hi[a]]) for a in range(3)]


def place_lattice(level, planes, grading):
    """A level of a gmsh or file mesh graded: along each graded axis a vertex at s, its
    place among the coarse mesh's `planes` (lattice_planes) as a fraction of their count
    (linear between planes: a refined vertex's s is its parents' mean, as on a box's
    lattice), moves to lower + phi(s) (upper - lower): the file's own spacing along that
    axis is replaced by the grading's. level.reference keeps the file's places (the
    refinement and the prolongation's search, as for a graded box)."""
    x = level.reference
    out = np.array(x, dtype=float, copy=True)
    for axis, spec in grading.items():
        (kind, value), = spec.items()
        i = AXES.index(axis)
        p = planes[i]
        t = np.interp(x[:, i], p, np.linspace(0.0, 1.0, p.size))
        out[:, i] = np.where(t >= 1.0, p[-1], p[0] + MAPS[kind](t, value) * (p[-1] - p[0]))
    level.coords, level.lattice = out, None
    v = level.dm.getCoordinatesLocal().duplicate()   # (DMRefine's mesh shares the DM's)
    v.setArray(out.ravel())
    level.dm.setCoordinatesLocal(v)


#: local_coordinates: a Newton step below this that no longer halves is round-off
STALL = 1e-10


def local_coordinates(xi, Xp, x, tol=1e-14, iterations=30):
    """On mapped levels (a graded box, bodies with a lower_surface): the place in [-1, 1]^3
    of fine vertices x (n, 3) in their parent cells Xp (n, 8, 3, HEX_REF order), the
    inverse of the parent's trilinear map, so that the parent's trilinear functions there
    are the coarse Q1 space's values at x: P interpolates exactly where the levels are
    nested. Newton (Gauss-Newton), vectorised, from the reference place xi (-1, 0, 1 per
    axis: the lattice's). Where xi is -1 or 1 the vertex lies on the parent's face: that
    component is kept, exactly (least squares in the others: on a curved face a fine
    vertex is off its parent's bilinear face by the sag), so a vertex on a face is given
    by that face's 4 corners alone and neighbouring parents agree on it. Stops when the
    steps are below tol (relative to 2, the cell's width in xi), or stop halving below
    STALL (round-off: a cell of 0.0035 at x = 3 has steps of ~1e-13 for ever, where the
    30 iterations took 10 of the graded beam's 24 s at Nd 32); on an axis-aligned box
    cell (a graded box) the map is affine per axis: the first step is exact."""
    free = xi == 0.0
    out = np.array(xi, dtype=float, copy=True)
    step = np.zeros_like(out)
    last = np.inf
    for _ in range(iterations):
        f = 1.0 + out[:, None, :] * HEX_REF[None, :, :]                  # (n, 8, 3)
        N = np.prod(f, axis=2) / 8.0                                      # (n, 8)
        dN = np.stack([HEX_REF[None, :, d] * np.prod(np.delete(f, d, axis=2), axis=2)
                       for d in range(3)], axis=2) / 8.0                  # (n, 8, 3)
        r = x - np.einsum("na,nai->ni", N, Xp)
        J = np.einsum("nai,naj->nij", Xp, dN) * free[:, None, :]          # free columns
        A = np.einsum("nki,nkj->nij", J, J) + np.eye(3) * (~free)[:, :, None]
        step = np.linalg.solve(A, np.einsum("nki,nk->ni", J, r)[..., None])[..., 0]
        out += step
        size = np.abs(step).max(initial=0.0)
        if size <= tol or size < STALL and size > 0.5 * last:
            break
        last = size
    if np.abs(step).max(initial=0.0) > 1e-8:
        raise MeshError("the inverse trilinear map of a mapped level did not converge")
    if out.size and np.abs(out[free]).max(initial=0.0) >= 1.0:
        raise MeshError("a mapped level's vertex is not inside its parent cell")
    return np.clip(out, -1.0, 1.0)
