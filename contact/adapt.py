"""Box meshes graded where the run's own error indicator puts the error (mesh.grading auto).

The error of a box mesh lives along a few edges (the clamped edge, the contact front,
where a traction ends): the cell indicator of a solved mesh (analysis/estimate.py:
cell_indicator, the change the last refinement made on each cell) shows them. For each
axis whose grading is `auto` (scene_grading.py; `-mesh_grading auto`: every axis):

  1. a pilot, the same scene at Nd / -mesh_grading_pilot with those axes uniform, is solved
     (its own coarse-to-fine levels, two where Nd has them: -c2f_levels 2 unless given;
     the indicator needs one, the local orders two);
  2. its squared indicator is summed over the slabs of cells along the axis
     (estimate.slab_errors), and mesh/grading.py's `equidistribute` turns the sums into
     the axis's `points` (cells denser where the error is, at most -mesh_grading_max_ratio
     between the largest and the smallest, neighbours within 1.5);
  3. the run proper is an ordinary graded box: every level of its hierarchy on the same map,
     so the multigrid, the coarse-to-fine start and the run's error estimate (its levels
     are one graded family) work as on any box; summary.json's `grading` holds the points
     (a scene may give them back: `grading: {x: {points: [...]}}`).

With -error_target (cli.py) there is no pilot after the first run: each run's grading comes
from the indicator of the run before it (`design(scene, problem)`), so the grading follows
the singularities as the mesh grows.
"""
import copy
import gc
import time

import numpy as np
from petsc4py import PETSc

from contact import options, scene_grading
from contact.analysis import estimate
from contact.fem import QUADRATIC
from contact.mesh import grading
from contact.problem import ContactProblem


def axes(sc):
    """The axes the run grades from the indicator: the scene's auto axes, every axis with
    -mesh_grading auto; none with -mesh_grading uniform (the scene's grading dropped) or
    off a box."""
    how = options.get("mesh_grading")
    if how not in ("scene", "auto", "uniform"):
        raise ValueError(f"-mesh_grading must be scene, auto or uniform, got {how!r}")
    mesh = sc["mesh"]
    if how == "uniform":
        mesh.pop("grading", None)
    if mesh.get("type", "box") != "box":
        if how == "auto" or scene_grading.auto_axes(mesh):
            raise ValueError(f"mesh.grading auto needs a box mesh, not a {mesh['type']} mesh")
        return []
    auto = list("xyz") if how == "auto" else scene_grading.auto_axes(mesh)
    if auto and not options.get("error_estimate"):
        raise ValueError("mesh.grading auto grades from the error indicator, which "
                         "-error_estimate 0 turns off")
    return auto


def design(sc, solved, auto):
    """A copy of scene `sc` whose `auto` axes are graded by the indicator of the solved
    problem `solved` (a box of the same extent), and the words for the summary."""
    if solved.error_indicator is None:
        raise ValueError(f"mesh.grading auto: the solve at Nd = {solved.nd} has no coarser "
                         "level, so no error indicator (a larger -nd, or -c2f_levels >= 1)")
    out = copy.deepcopy(sc)
    mesh = out["mesh"]
    g = mesh.get("grading")
    g = {} if not isinstance(g, dict) else g
    lo, hi = np.asarray(mesh["lower"], float), np.asarray(mesh["upper"], float)
    order = 2 if solved.element in QUADRATIC else 1
    ratio = options.get("mesh_grading_max_ratio")
    info = {}
    for a in auto:
        i = grading.AXES.index(a)
        edges, E = estimate.slab_errors(solved, i)
        coarse = solved.coarse_slabs[i][1] if solved.coarse_slabs is not None else None
        if coarse is not None and 2 * coarse.size != E.size:
            coarse = None
        cells = mesh["cells_per_nd"][i] * mesh["nd"] * (2 if order == 2 else 1)
        pts = grading.equidistribute(edges, E, order, cells, coarse, max_ratio=ratio)
        g[a] = {"points": [round(float(p), 10) for p in pts]}
        h = np.diff(grading.points(np.linspace(0.0, 1.0, cells + 1), pts)) * (hi[i] - lo[i])
        info[a] = {"points": g[a]["points"], "smallest": float(h.min()),
                   "largest": float(h.max()), "from_nd": solved.nd}
    mesh["grading"] = g
    return out, info


def pilot_scene(sc, auto):
    """The pilot: `sc` at Nd / -mesh_grading_pilot, its auto axes uniform."""
    out = copy.deepcopy(sc)
    mesh = out["mesh"]
    div = options.get("mesh_grading_pilot")
    if div < 1 or mesh["nd"] // div < 1:
        raise ValueError(f"-mesh_grading_pilot {div}: the pilot needs Nd / {div} >= 1 "
                         f"(Nd = {mesh['nd']})")
    mesh["nd"] = mesh["nd"] // div
    g = mesh.get("grading")
    if isinstance(g, dict):
        kept = {k: v for k, v in g.items() if k not in auto}
        mesh["grading"] = kept
        if not kept:
            del mesh["grading"]
    else:
        mesh.pop("grading", None)
    return out


def graded_scene(sc, comm, auto, solved=None):
    """(scene, info): `sc` with its `auto` axes graded from the indicator of `solved` (a
    pilot solved first, and released, where solved is None); info for summary.json's
    `grading`. The caller builds the ContactProblem once `solved` is released."""
    t0, pilot_time = time.perf_counter(), None
    if solved is None:       # two levels below the pilot where Nd has them: its indicator
        with options.inserted({"c2f_levels": "2"}):         # and each slab's local order
            solved = ContactProblem(pilot_scene(sc, auto), comm).solve()
        pilot_time = time.perf_counter() - t0
    scene, info = design(sc, solved, auto)
    nd, el = solved.nd, solved.element
    del solved
    gc.collect()
    PETSc.Sys.Print("grading from the error indicator at Nd = %d (%s%s): %s" % (
        nd, el, "" if pilot_time is None else f", pilot solved in {pilot_time:.2f} s",
        "; ".join(f"{a} cells {v['smallest']:.3g} to {v['largest']:.3g}"
                  for a, v in info.items())), comm=comm)
    return scene, {"axes": info, "pilot_s": pilot_time}
