"""Boxes graded where the run's own error indicator puts the error (mesh.grading auto).

The error of a box mesh lives along a few edges (the clamped edge, the contact front,
where a traction ends): the cell indicator of a solved mesh (analysis/estimate.py:
cell_indicator, the change the last refinement made on each cell) shows them. For each
axis whose grading is `auto` (scene_grading.py; `-mesh_grading auto`: every axis):

  1. a pilot, the same scene at Nd / -mesh_grading_pilot (2 for q1, 1 for q2) with those
     axes uniform, is solved (its own coarse-to-fine levels, two where Nd has them:
     -c2f_levels 2 unless given; the indicator needs one, the local orders two);
  2. its squared indicator is summed over the slabs of cells along the axis
     (estimate.slab_errors), and mesh/grading.py's `equidistribute` turns the sums into
     the axis's `points` (cells denser where the error is, at most -mesh_grading_max_ratio
     between the largest and the smallest, neighbours within 1.5);
  3. the run proper is an ordinary graded box: every level of its hierarchy on the same map,
     so the multigrid, the coarse-to-fine start and the run's error estimate (its levels
     are one graded family) work as on any box; summary.json's `grading` holds the points
     (a scene may give them back: `grading: {x: {points: [...]}}`).

A scene with bodies (mesh/bodies.py; q1, bbar, q2, q2p1, side by side too) grades each
body's auto axes (its `grading: auto`, or every body's with -mesh_grading auto) from the
indicator on its own cells, its slabs those of its box (a curved lower_surface moves z,
not the slabs); no local orders (its element's: 1 for q1 and bbar, 2 for q2 and q2p1).

A gmsh or file mesh that is a tensor-product hexahedral mesh of a box (gmsh's extruded
layers or transfinite volumes: mesh/grading.py lattice_planes) grades as
a box, its lattice the file's planes (refined with -mesh_refine): the pilot is the mesh
itself (the file has no coarser copy), and the points re-place those planes along each
axis, the file's own spacing there replaced. A hexahedral mesh of a box on no lattice
(unstructured) is graded by a per-axis map of the box (grading.box_planes), the
indicator summed in equal slabs (estimate.file_bins).

With -error_target (cli.py) there is no pilot after the first run: each run's grading
comes from the indicator of the run before it (`design(scene, problem)`), so the grading
follows the singularities as the mesh grows.
"""
import copy
import gc
import time

import numpy as np
from petsc4py import PETSc

from contact import options, scene_grading
from contact.analysis import estimate, goal as goals
from contact.fem import QUADRATIC
from contact.fem.discretisation import body_elements, element_of
from contact.mesh import bodies, grading
from contact.mesh.bodies import read as read_body
from contact.problem import ContactProblem


def axes(sc):
    """What the run grades from the indicator: a box's auto axes ["x", ...] (the scene's,
    every axis with -mesh_grading auto), or for a scene with bodies (mesh type bodies,
    q1) the pairs [(body, axis), ...] of the bodies' own auto gradings (every body's every
    axis with -mesh_grading auto); none with -mesh_grading uniform (the scene's gradings
    dropped). A gmsh or file mesh's axes as a box's (a tensor-product mesh of a box:
    mesh/grading.py place_lattice; its pilot is the mesh itself)."""
    how = options.get("mesh_grading")
    if how not in ("scene", "auto", "uniform"):
        raise ValueError(f"-mesh_grading must be scene, auto or uniform, got {how!r}")
    mesh = sc["mesh"]
    kind = mesh.get("type", "box")
    bodies = mesh.get("bodies", {}) if kind == "bodies" else {}
    if how == "uniform":
        mesh.pop("grading", None)
        for b in bodies.values():
            b.pop("grading", None)
    if kind == "bodies":                 # (a gmsh body, mesh: {...}, has no box to grade)
        auto = [(name, a) for name, b in bodies.items() if not read_body(b) for a in (
            "xyz" if how == "auto" else scene_grading.auto_axes(b))]
        if how == "auto" and not auto:
            raise ValueError("mesh.grading auto needs a box mesh or box bodies, not only "
                             "gmsh bodies")
    else:                   # a box, or a gmsh or file mesh (a box's lattice: hierarchy.py)
        auto = list("xyz") if how == "auto" else scene_grading.auto_axes(mesh)
    if auto:
        goal()                          # (-error_quantity checked before any solve)
    if auto and not options.get("error_estimate"):
        raise ValueError("mesh.grading auto grades from the error indicator, which "
                         "-error_estimate 0 turns off")
    return auto


def design(sc, solved, auto, finer=1):
    """A copy of scene `sc` whose `auto` axes (axes(): a box's, or (body, axis) pairs) are
    graded by the indicator of the solved problem `solved` (the same box or bodies), and
    the words for the summary (keyed "x" on a box, "body.x" on bodies). finer: a gmsh or
    file mesh's run is refined once more than `solved` (2; -error_target), or not (1)."""
    if solved.error_indicator is None:
        raise ValueError(f"mesh.grading auto: the solve at Nd = {solved.nd} has no coarser "
                         "level, so no error indicator (a larger -nd, or -c2f_levels >= 1)")
    out = copy.deepcopy(sc)
    mesh = out["mesh"]
    nodes = 2 if solved.element in QUADRATIC else 1       # q2's cells: its nodes' mesh's
    ratio = options.get("mesh_grading_max_ratio")
    info = {}
    # the finest level's Nd over the scene's: 1, but 2^K with a gmsh body (-nd its coarse
    # level's, -mesh_refine K)
    refined = max(1, solved.nd // solved.scene["mesh"]["nd"])
    for key, box, counts, i, slabs, coarse, order in _targets(mesh, solved, auto):
        g = box.get("grading")
        g = box["grading"] = {} if not isinstance(g, dict) else g
        edges, E = slabs
        if coarse is not None and 2 * coarse.size != E.size:
            coarse = None
        # a gmsh or file mesh (counts None): the pilot's planes are the run's own
        cells = finer * (edges.size - 1) if counts is None else \
            counts[i] * mesh["nd"] * refined * nodes
        pts = grading.equidistribute(edges, E, order, cells, coarse, max_ratio=ratio)
        g[grading.AXES[i]] = {"points": [round(float(p), 10) for p in pts]}
        h = np.diff(grading.points(np.linspace(0.0, 1.0, cells + 1), pts)) * (
            edges[-1] - edges[0])
        info[key] = {"points": g[grading.AXES[i]]["points"], "smallest": float(h.min()),
                     "largest": float(h.max()), "from_nd": solved.nd}
    return out, info


def _targets(mesh, solved, auto):
    """Per graded axis: (info key, the box's dict (lower, upper, grading: the mesh section
    or a body), its cells per Nd, the axis index, (edges, E) of the solved problem's
    indicator along it, the coarser level's E or None, the element's order). A body's
    slabs are its own cells' (disc.body_of), on its box's lattice placed by its grading
    alone (level.reference through mesh/bodies.py's map without lower_surface: the slabs
    of a curved lower face are those of its box); no coarser level's (local orders: its
    element's, 1 for q1 and bbar beside q2's nodes, 2 for q2 and q2p1)."""
    if mesh.get("type", "box") != "bodies":
        counts = mesh["cells_per_nd"] if mesh.get("type", "box") == "box" else None
        order = 2 if solved.element in QUADRATIC else 1
        for a in auto:
            i = grading.AXES.index(a)
            coarse = solved.coarse_slabs[i][1] if solved.coarse_slabs is not None else None
            yield a, mesh, counts, i, estimate.slab_errors(solved, i), coarse, order
        return
    disc, names, places = solved.disc, list(mesh["bodies"]), {}
    orders = [2 if e in QUADRATIC else 1 for e in body_elements(solved.scene)]
    for name, a in auto:
        b, j = mesh["bodies"][name], names.index(name)
        if name not in places:                  # the solved scene's body, its box's places
            places[name] = bodies.body_map(disc.level.reference,
                                           dict(disc.bodies[name], lower_surface=None))
        i = grading.AXES.index(a)
        yield f"{name}.{a}", b, b["cells"], i, estimate.slab_errors(
            solved, i, cells=np.flatnonzero(disc.body_of == j), coords=places[name]), None, \
            orders[j]


def goal():
    """The quantity the grading aims at (-error_quantity): "force" or "max_u", whose dual
    solution weighs the indicator (analysis/goal.py), or None for the energy (the
    indicator alone)."""
    q = options.get("error_quantity")
    if q not in ("energy",) + goals.GOALS:
        raise ValueError(f"-error_quantity must be one of energy, {', '.join(goals.GOALS)}, "
                         f"got {q!r}")
    return None if q == "energy" else q


def pilot_scene(sc, auto):
    """The pilot: `sc` at Nd / -mesh_grading_pilot, its auto axes uniform."""
    out = copy.deepcopy(sc)
    mesh = out["mesh"]
    div = options.get("mesh_grading_pilot")
    if mesh.get("type", "box") in ("gmsh", "file"):   # its lattice is the file's: no coarser
        if div not in (None, 1):                       # copy of it to solve
            raise ValueError(f"-mesh_grading_pilot {div}: a gmsh or file mesh's pilot is "
                             f"the mesh itself (-mesh_grading_pilot 1)")
        div = 1
    if div is None:                   # q2's pilot at Nd / 2 sees too few slabs to place its
        div = 1 if element_of(sc) in QUADRATIC else 2     # cells (adaptive.md)
    if div < 1 or mesh["nd"] // div < 1:
        raise ValueError(f"-mesh_grading_pilot {div}: the pilot needs Nd / {div} >= 1 "
                         f"(Nd = {mesh['nd']})")
    mesh["nd"] = mesh["nd"] // div
    if mesh.get("type", "box") == "bodies":
        boxes = [(mesh["bodies"][n], [a for m, a in auto if m == n]) for n in mesh["bodies"]]
    else:
        boxes = [(mesh, auto)]
    for box, axes_ in boxes:
        g = box.get("grading")
        if isinstance(g, dict):
            kept = {k: v for k, v in g.items() if k not in axes_}
            box["grading"] = kept
            if not kept:
                del box["grading"]
        elif axes_:
            box.pop("grading", None)
    return out


def _check_pilot(pilot):
    """One line, before the pilot is solved, where it would have no coarser level to
    compare with, so no error indicator to grade by."""
    below, files = pilot.levels_below()
    if below >= 1 and pilot.c2f_asked != 0:
        return
    why = ("-c2f_levels 0 solves no coarser level" if pilot.c2f_asked == 0 else
           "a gmsh or file mesh is one level: -mesh_refine 1 or more, the file's mesh the "
           "coarser one" if files else
           f"Nd = {pilot.nd} has no factor of 2: an -nd with one more factor of 2")
    raise ValueError(f"mesh.grading auto: its pilot at Nd = {pilot.nd} would have no coarser "
                     f"level, so no error indicator ({why})")


def graded_scene(sc, comm, auto, solved=None, finer=1):
    """(scene, info): `sc` with its `auto` axes graded from the indicator of `solved` (a
    pilot solved first, and released, where solved is None); info for summary.json's
    `grading` (finer: design's). The caller builds the ContactProblem once `solved` is
    released."""
    t0, pilot_time = time.perf_counter(), None
    if solved is None:       # two levels below the pilot where Nd has them: its indicator
        with options.inserted({"c2f_levels": "2"}):         # and each slab's local order
            pilot = ContactProblem(pilot_scene(sc, auto), comm, goal=goal())
            _check_pilot(pilot)
            solved = pilot.solve()
        del pilot
        pilot_time = time.perf_counter() - t0
    scene, info = design(sc, solved, auto, finer)
    nd, el = solved.nd, solved.element
    del solved
    gc.collect()
    PETSc.Sys.Print("grading from the error indicator at Nd = %d (%s%s): %s" % (
        nd, el, "" if pilot_time is None else f", pilot solved in {pilot_time:.2f} s",
        "; ".join(f"{a} cells {v['smallest']:.3g} to {v['largest']:.3g}"
                  for a, v in info.items())), comm=comm)
    return scene, {"axes": info, "pilot_s": pilot_time}
