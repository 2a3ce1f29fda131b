"""The discretisation error of a run, estimated from its own mesh hierarchy.

The coarse-to-fine start solves the scene on Nd/4, Nd/2, ... before Nd (problem.py); each
level records the quantities a user reads (QUANTITIES: max |u|, the contact force's normal
and tangential resultants, the energy J). In the asymptotic range q(h) = q* + C h^p, h =
1/Nd, and three levels give q*, p and C (generalised Richardson extrapolation,
contact/analysis/convergence.py): the estimated error of this run's value is |q(Nd) - q*|
and the extrapolated value q* is printed beside it; with four levels or more, the
extrapolation from the next triple gives q*'s own error estimate (their difference).
Where the levels are not in the asymptotic range (the differences change sign or do not
shrink, or the observed order lies outside ORDERS for the element) the estimate says so in
words instead of a number; except where they oscillate and converge (the differences change
sign, the last the smaller: Stern et al., "Comprehensive approach to verification and
validation of CFD simulations", J. Fluids Eng. 123, 2001, 793-802, "oscillatory
convergence"), where the error is bounded by half the range of the last three levels
(their U_G = (S_U - S_L) / 2): conservative, with no order and no extrapolation. The
coarse levels are solved to COARSE_RTOL (-newton_rtol of the coarse levels when the
estimate is on): the Newton iteration converges quadratically
there, so its error is orders below the level differences used (runs/results/estimate.md
records both).
"""
import math

import numpy as np
from mpi4py import MPI

from contact import fem
from contact.analysis import stress
from contact.solvers import residuals as res
from contact.analysis import convergence
from contact.mesh import MeshError
from contact.mesh.grading import lattice_planes

#: summary.json key -> words
QUANTITIES = {"max_displacement": "max |u|", "normal_force": "contact force N",
              "tangential_force": "contact force T", "energy": "energy J"}
#: levels whose values agree to this (relative) give the same value: no estimate to make
SAME = 1e-10

#: observed orders accepted as asymptotic, per element (h = 1/Nd; q2's Nd counts its
#: elements): outside, the estimate is not given. An order observed far above the element's
#: a-priori order is pre-asymptotic, and C h^p with it understates the error. q1, bbar: 1.5
#: times the energy's and the force's order 2 (Hertz's contact force at Nd = 2, 4, 8: order
#: 3.75, effectivity 0.35; runs/results/estimate.md). q2, q2p1: the contact limits the
#: solution to H^(5/2 - eps) at the contact boundary, so the energy and the forces converge
#: at most as h^3, not h^4; the bound is 3.5. Measured on the paper's beam
#: (runs/results/estimate.md, 2026-11-28): q2 triples of orders 1.1 to 2.2 have
#: effectivities 0.5 to 1.7, the three of orders 4.27 to 4.64 (max |u| at N = 1, 2, 4; max
#: |u| and T on the graded beam at 2, 4, 8) 0.02 to 0.1
ORDERS = {"q1": (0.5, 3.0), "bbar": (0.5, 3.0), "q2": (0.5, 3.5), "q2p1": (0.5, 3.5)}
#: max |u|, a point value at the loaded end's edge (where the traction ends on the contact
#: face), with q2: every triple on record of order 1.5 or less within effectivity 0.58-1.7,
#: both above understating it 8-50 times (order 2.88 on the auto-graded beam at 3, 6, 12:
#: 0.13; 4.27 on the bump-graded one: 0.1; runs/results/estimate.md)
POINT_ORDERS = {"q2": (0.5, 2.5), "q2p1": (0.5, 2.5)}
#: the coarse levels' -newton_rtol when the estimate is on
COARSE_RTOL = 1e-10
#: the words that open a quantity's note where its levels are not in the asymptotic range
#: (-error_target refines on: cli.py)
NOT_ASYMPTOTIC = "not in the asymptotic range"
#: ... and where they oscillate and converge (their error: half the levels' range)
OSCILLATING = "oscillating"


def cell_indicator(problem, x0):
    """Where the error lives: eta_K = ||u_h - P u_2h||_a on each local output cell K, the
    energy norm (the cell's stiffness K_e) of the difference between this run's solution
    and the coarse level's prolonged to this mesh (x0, the coarse-to-fine start): the part
    of the solution the last refinement changed, large where the coarse mesh resolved
    least (at singularities: the clamped edge, the contact front). Cells are the output
    mesh's hexahedra: q1 and bbar their own elements (exact element energy); q2 and q2p1
    the octants of their elements, with the trilinear interpolant of the difference (an
    indicator, not the element's own energy). Returns (eta (nc,), sqrt(sum eta^2) over
    ranks, the same norm of u itself, D (nc, 3)): D[K, a] = mu int_K |d e / d x_a|^2, the
    part of the change that varies along axis a (trilinear e, 2 x 2 x 2 Gauss points):
    an edge singularity along x changes e across y and z, not along x, so refining along
    x would not reduce it (contact/adapt.py grades each axis by its own part)."""
    d, d0 = problem.displacement(problem.x), problem.displacement(x0)
    u = stress.local_values(problem.dm, d.getArray(readonly=True).reshape(-1, 3))
    e = u - stress.local_values(problem.dm, d0.getArray(readonly=True).reshape(-1, 3))
    for v, x in ((d, problem.x), (d0, x0)):
        if v is not x:                  # (x itself where there is no u_D and no frame)
            v.destroy()
    return cell_parts(problem, e, u)


def cell_parts(problem, e, u=None):
    """cell_indicator's (eta, its total, ||u||_a (0 without u), D) of the local vertex
    values e (nv, 3) in x, y, z (and u): also the dual's (goal.py)."""
    conn, coords = problem.conn, problem.coords
    mat = problem.scene["material"]
    lam, mu = fem.lame(mat["young"], mat["poisson"])
    kind = "bbar" if problem.element == "bbar" else "q1"
    eta, norm = np.zeros(conn.shape[0]), np.zeros(conn.shape[0])
    D = np.zeros((conn.shape[0], 3))
    fields = ((eta, e),) if u is None else ((eta, e), (norm, u))
    for a in range(0, conn.shape[0], fem.CHUNK):
        c = conn[a:a + fem.CHUNK]
        dNdx, wdet = fem.geometry(coords[c])                        # (c, g, 8, 3), (c, g)
        G = np.matmul(dNdx.transpose(0, 1, 3, 2), e[c][:, None])    # (c, g, axis, comp)
        D[a:a + fem.CHUNK] = mu * np.einsum("cg,cgak->ca", wdet, G * G)
        K, shape = fem.element_stiffness_shapes(coords[c], lam, mu, kind)
        for out, v in fields:
            w = v[c].reshape(c.shape[0], -1)
            if shape is None:                       # a matrix per cell
                out[a:a + fem.CHUNK] = np.einsum("ci,cij,cj->c", w, K, w)
                continue
            part = out[a:a + fem.CHUNK]
            for s in range(K.shape[0]):             # one product per distinct cell shape
                i = np.flatnonzero(shape == s)
                part[i] = np.einsum("ci,ci->c", w[i] @ K[s], w[i])
    comm = problem.comm.tompi4py()
    tot = comm.allreduce(np.array([eta.sum(), norm.sum()]))
    return np.sqrt(np.maximum(eta, 0.0)), math.sqrt(max(tot[0], 0.0)), \
        math.sqrt(max(tot[1], 0.0)), D


def slab_errors(problem, axis, cells=None, coords=None):
    """Where the error lives along one axis (a box mesh): (edges, E), the cell planes of
    this run's output cells normal to `axis` (0, 1, 2; global, sorted: the slabs between
    them) and the indicator's part along the axis (cell_indicator's D[:, axis]) summed
    over each slab's cells, on every rank. For contact/adapt.py (mesh.grading auto).
    cells: only these local cells (a body's), their vertices' planes; coords: the local
    vertices' places to read the planes from (default the mesh's). A mesh whose vertices
    lie on no lattice of planes (an unstructured hexahedral mesh of a box: file_bins):
    equal slabs, about as many as its cells along the axis, each cell in the slab of its
    centroid."""
    comm = problem.comm.tompi4py()
    x = (problem.coords if coords is None else coords)[:, axis]
    conn = problem.conn if cells is None else problem.conn[cells]
    part = (problem.error_indicator[3] if problem.goal_parts is None
            else problem.goal_parts)[:, axis]
    if cells is not None:
        part = part[cells]
    mine = np.unique(x if cells is None else x[conn])
    planes = np.unique(np.concatenate(comm.allgather(mine)))
    span = planes[-1] - planes[0]
    edges = planes[np.concatenate([[True], np.diff(planes) > 1e-9 * span])]
    bins = file_bins(problem) if cells is None and coords is None and \
        problem.scene["mesh"].get("type", "box") in ("gmsh", "file") else None
    if bins is not None:
        edges = np.linspace(planes[0], planes[-1], bins[axis] + 1)
    E = np.zeros(edges.size - 1)
    if conn.shape[0]:
        cen = x[conn].mean(axis=1)
        j = np.clip(np.searchsorted(edges, cen) - 1, 0, E.size - 1)
        E = np.bincount(j, weights=part, minlength=E.size)
    return edges, comm.allreduce(E)


def file_bins(problem):
    """None where the mesh's vertices lie on a lattice of planes (a box, or a tensor-product
    file mesh: mesh/grading.py lattice_planes); else, per axis, about its cells along it:
    the extent over the mean cell's edge, (volume / cells)^(1/3), at least 4 (an
    unstructured mesh of a box, graded by a per-axis map: grading.box_planes)."""
    try:
        lattice_planes(problem.coords, problem.coordinates.getSize() // 3, problem.comm)
        return None
    except MeshError:
        pass
    comm, x = problem.comm.tompi4py(), problem.coords
    lo, hi = np.empty(3), np.empty(3)
    comm.Allreduce(x.min(axis=0) if x.size else np.full(3, np.inf), lo, op=MPI.MIN)
    comm.Allreduce(x.max(axis=0) if x.size else np.full(3, -np.inf), hi, op=MPI.MAX)
    ext = hi - lo
    h = (float(np.prod(ext)) / comm.allreduce(problem.conn.shape[0])) ** (1.0 / 3.0)
    return [max(4, int(round(e / h))) for e in ext]


def indicator_summary(problem):
    """summary.json's `error_indicator`: the total, relative to ||u||_a, and the largest
    cell's value and centroid; None without a coarse level."""
    eta = getattr(problem, "error_indicator", None)
    if eta is None:
        return None
    cells, total, unorm = eta[:3]
    cen = problem.coords[problem.conn].mean(axis=1) if problem.conn.shape[0] else \
        np.zeros((0, 3))
    value, where = stress.peak(problem.comm.tompi4py(), cells, cen)
    return {"energy_norm": total, "relative": total / unorm if unorm > 0 else None,
            "max": {"value": value if np.isfinite(value) else None, "location": where},
            "of": "||u_h - P u_2h||_a per cell: the change of the last refinement "
                  "(contact/analysis/estimate.py)"}


def quantities(problem):
    """QUANTITIES of a solved problem (the contact force from its contact state, its normal
    part along the normals summary.json's contact_result takes: a curved pair's per node)."""
    comm = problem.comm.tompi4py()
    out = {"max_displacement": res.max_displacement(comm, problem.displacement()),
           "energy": res.energy(problem), "normal_force": None, "tangential_force": None}
    if problem.cs is not None and problem.cs.size:
        r = stress.resultants(comm, stress.contact_state(problem), stress.normals(problem))
        out["normal_force"], out["tangential_force"] = r["normal"], r["tangential"]
    return out


def from_levels(levels, element):
    """The estimate (a dict per quantity, JSON-ready) from levels [(nd, quantities), ...],
    coarse to fine, the last this run's; None with fewer than three levels."""
    if len(levels) < 3:
        return None
    nds = [nd for nd, _ in levels]
    out = {}
    for key in QUANTITIES:
        lo, hi = (POINT_ORDERS if key == "max_displacement" and element in POINT_ORDERS
                  else ORDERS).get(element, (0.5, 3.0))
        vals = [q.get(key) for _, q in levels]
        if any(v is None for v in vals):
            continue
        fine = vals[-1]
        entry = {"value": fine, "levels": dict(zip(map(str, nds), vals))}
        spread = max(vals[-3:]) - min(vals[-3:])
        if spread <= SAME * max(abs(v) for v in vals[-3:]):
            entry.update(error=spread, order=None, extrapolated=fine, extrapolated_error=None,
                         note=f"the same on every level to rounding (Nd = "
                              f"{', '.join(map(str, nds[-3:]))}): the data set it (a "
                              f"prescribed displacement, say), no discretisation error")
            out[key] = entry
            continue
        r = convergence.richardson([1.0 / n for n in nds[-3:]], vals[-3:])
        d1, d2 = vals[-3] - vals[-2], vals[-2] - vals[-1]
        if d1 * d2 < 0 and abs(d2) < abs(d1):          # oscillatory convergence
            entry.update(error=spread / 2, order=None, extrapolated=None,
                         extrapolated_error=None,
                         note=f"{OSCILLATING}: the differences between levels change sign "
                              f"and shrink (Nd = {', '.join(map(str, nds[-3:]))}); the error "
                              "bounded by half their range (Stern et al. 2001)")
            out[key] = entry
            continue
        if r is None or not lo <= r[1] <= hi:
            why = ("the differences between levels change sign" if d1 * d2 <= 0 else
                   "the differences do not shrink" if r is None else
                   f"observed order {r[1]:.2f} outside {lo:g} to {hi:g} for {element}")
            entry.update(error=None, order=None, extrapolated=None,
                         note=f"{NOT_ASYMPTOTIC}: {why} (Nd = "
                              f"{', '.join(map(str, nds[-3:]))})")
            out[key] = entry
            continue
        qstar, p, _ = r
        entry.update(error=abs(fine - qstar), order=p, extrapolated=qstar,
                     extrapolated_error=None, note=None)
        if len(levels) >= 4:
            r2 = convergence.richardson([1.0 / n for n in nds[-4:-1]], vals[-4:-1])
            if r2 is not None:
                entry["extrapolated_error"] = abs(qstar - r2[0])
        out[key] = entry
    return out


#: why T is not estimated without friction
FRICTIONLESS = ("not estimated: frictionless, T = 0 (the value is rounding)")


def of_run(problem, s):
    """(from_levels of the coarse runs and this run, words) for summary.json: this run's
    QUANTITIES from its summary s (computed there once)."""
    if not problem.estimating:
        return None, "no estimate: -error_estimate 0"
    cr = s["contact_result"] or {}
    this = {"max_displacement": s["max_displacement"], "energy": s["energy"],
            "normal_force": cr.get("normal"), "tangential_force": cr.get("tangential")}
    levels = [(r["nd"], r["quantities"]) for r in problem.coarse_runs if "quantities" in r]
    est = from_levels(levels + [(problem.nd, this)],   # (q1 and q2 bodies: q1's orders)
                      "q1" if problem.disc.mixed else problem.element)
    if est is not None and "tangential_force" in est and s["mode"] == "frictionless":
        est["tangential_force"].update(error=None, order=None, extrapolated=None,
                                       note=FRICTIONLESS)
    if est is not None:
        return est, (f"discretisation error from the levels Nd = "
                     f"{', '.join(str(n) for n, _ in levels + [(problem.nd, None)])}")
    why = (f"{len(levels) + 1} level(s) solved (three are needed: a box Nd with two factors "
           "of 2, Nd >= 16; -c2f_levels; a mesh file has one: -mesh_refine 2 -c2f_levels 2)")
    return None, f"no estimate: {why}"


def relative_error(e):
    """A quantity's estimated error relative to its extrapolated value (to its value where
    there is no extrapolation: an oscillation's bound); None without an error or a scale."""
    ref = e["value"] if e["extrapolated"] is None else e["extrapolated"]
    return e["error"] / abs(ref) if e["error"] is not None and ref else None


def lines(est, nds):
    """Console lines of an estimate (summary's `error_estimate`)."""
    if est is None:
        return []
    out = [f"error estimate (discretisation, from this run's levels Nd = "
           f"{', '.join(map(str, nds))}):"]
    for key, words in QUANTITIES.items():
        e = est.get(key)
        if e is None:
            continue
        if e["error"] is None:
            out.append(f"  {words:16s} {e['value']:.6e}  {e['note']}")
            continue
        if (e["note"] or "").startswith(OSCILLATING):
            rel = relative_error(e)
            rel = math.inf if rel is None else rel
            out.append(f"  {words:16s} {e['value']:.6e} +- {e['error']:.1e} "
                       f"({100 * rel:.2g} %), {e['note']}")
            continue
        if e["order"] is None:                    # the same on every level (from_levels)
            out.append(f"  {words:16s} {e['value']:.6e} +- {e['error']:.1e}  {e['note']}")
            continue
        rel = relative_error(e)
        rel = math.inf if rel is None else rel
        out.append(f"  {words:16s} {e['value']:.6e} +- {e['error']:.1e} ({100 * rel:.2g} %), "
                   f"order {e['order']:.2f}; extrapolated {e['extrapolated']:.6e}")
    return out
