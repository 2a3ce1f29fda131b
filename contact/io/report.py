"""The run's summary: summary.json's dictionary and the Table-1-style console lines."""
import resource

import petsc4py
from petsc4py import PETSc

from contact.analysis import estimate, stress
from contact.solvers import residuals as res
from contact.solvers.loop import CONVERGED_ROUNDOFF


def _tolerances(problem):
    """The tolerances the loops used (options included), else the scene's."""
    sol = problem.scene["solver"]
    loops = {"apg_rtol": problem.apg, "uzawa_rtol": problem.uzawa, "fp_rtol": problem.fp}
    tol = {k: (lp.rtol if lp is not None else sol[k]) for k, lp in loops.items()}
    if problem.inner is not None and problem.apg is None:
        tol[problem.inner.prefix + "rtol"] = problem.inner.rtol
    return tol


def _pairs(problem):
    """(contact_pair, contact_pairs) of summary.json (_summary)."""
    d = problem.disc
    if d.pair is None:
        return None, None
    forces, bnd = stress.pair_results(problem), problem.scene["boundary"]
    fr = problem.scene.get("contact", {}).get("friction", 0.0)
    each = {name: {"slave": slave, "master": master, "slave_nodes": p["n_slave"],
                   "normal": [float(c) for c in p["normal"]],
                   "friction": bnd[name].get("friction", fr), "contact_result": forces[name]}
            for (name, slave, master), p in zip(d.pair_bodies, d.pair.pairs)}
    one = None
    if len(each) == 1:
        one = {k: v for k, v in next(iter(each.values())).items()
               if k not in ("contact_result", "friction")}
    return one, each


def summary(problem, time_total):
    """The dictionary written to summary.json (keys documented in the README)."""
    s = _summary(problem, time_total)
    s["error_estimate"], s["error_estimate_note"] = estimate.of_run(problem, s)
    s["error_indicator"] = estimate.indicator_summary(problem)
    # mesh.grading auto (contact/adapt.py): each axis's points, chosen from the error
    # indicator of the solve at Nd = from_nd (a pilot's, taking pilot_s; or the run
    # before's under -error_target); None: the scene's grading as written
    s["grading"] = getattr(problem, "grading_info", None)
    return s


def _summary(problem, time_total):
    comm = problem.comm
    mpicomm = comm.tompi4py()
    pair, pairs = _pairs(problem)
    return {
        "scene": problem.scene.get("name", "scene"),
        "nd": problem.nd,
        "ranks": comm.getSize(),
        "petsc_version": "%d.%d.%d" % PETSc.Sys.getVersion(),
        "petsc4py_version": petsc4py.__version__,
        "mode": problem.mode,
        "solver_mode": problem.solver_mode,
        "partitioner": problem.partitioner,
        "mesh": problem.hierarchy.describe(),        # hierarchy.py: how it was built
        "element": problem.element,        # fem.ELEMENTS (bodies: q2 where one is q2 or q2p1)
        "body_elements": None if problem.disc.body_element is None else
        dict(zip(problem.disc.bodies, problem.disc.body_element)),
        "mesh_levels": [lv.nd for lv in problem.hierarchy.levels],
        "dofs": problem.n_dofs,
        "nonzeros": int(problem.A.getInfo()["nz_used"]),
        "contact_nodes": problem.cs.n_paper if problem.cs is not None else 0,
        "contact_nodes_active": problem.cs.size if problem.cs is not None else 0,
        "friction": problem.scene.get("contact", {}).get("friction", 0.0),
        "uzawa_r": problem.scene["solver"]["uzawa_r"],
        "tolerances": _tolerances(problem),
        "lipschitz": problem.apg.lipschitz() if problem.apg is not None else None,
        "iterations": problem.iterations(),
        "coarse_runs": problem.coarse_runs,          # -c2f_levels: the coarse solves first
        "time_s": {"setup": problem.time_setup, "solve": problem.time_solve,
                   "total": time_total},
        "normal_force": problem.normal_force(),
        "loading": problem.loading,
        "load_steps": problem.load_steps,
        "held_by_friction": problem.friction_held is not None,
        "foundation_normal": [float(c) for c in problem.normal],
        "contact_frame": problem.frame is not None,
        # several bodies (scene_bodies.py): their names; a scene with one contact pair its
        # slave and master bodies and slave nodes (contact_result is then the master's
        # force on the slave body), with several null; `contact_pairs` each pair's by its
        # part's name, its contact_result too; None: one body on the foundation
        "bodies": list(problem.disc.bodies) if problem.disc.bodies is not None else None,
        "contact_pair": pair,
        "contact_pairs": pairs,
        "steps": problem.step_log,
        "skipped": problem.skipped,
        "energy": res.energy(problem),
        "max_displacement": res.max_displacement(mpicomm, problem.displacement()),
        "residuals": problem.residuals or res.residuals(problem),
        "converged": bool(problem.converged),
        # why the (last) solve's innermost loop stopped, and for CONVERGED_ROUNDOFF its
        # relative round-off floor eps ||A||_inf ||x|| / ||r(0)|| (coulomb.py); each load
        # increment's in `steps`
        "reason": problem.inner.reason if problem.inner is not None else None,
        "residual_floor": getattr(problem.inner, "floor", None),
        # the load continuation's sub-steps s of the (last) solve ([]: none was needed)
        "load_substeps": list(getattr(problem.inner, "load_substeps", [])),
        # peak resident memory of each rank so far (Linux ru_maxrss is in KiB)
        "peak_rss_mib": mpicomm.allgather(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
                                          / 1024.0),
        # contact_result (resultant force, normal and tangential; contact, stick and slip
        # areas), contact_result_steps (per load increment), von_mises_max (stress.py)
        **stress.summary(problem),
    }


def _inner(s):
    """(column label, first count, total in words) of the inner solver's iterations: a
    linear run's (inner "none") are its KSP iterations."""
    it = s["iterations"]
    name = it.get("inner", "apg")
    if name == "none":
        return "KSP its", it["ksp_total"], f"KSP its {it['ksp_total']}"
    return f"{name.upper()}(1st)", it["inner_first"], f"{name.upper()} total {it['inner_total']}"


def header(s):
    return (f"{'Nd':>4} {'n_p':>9} {'n_d':>7} {_inner(s)[0]:>9} {'Uzawa(mean)':>11} "
            f"{'FP':>4} {'time, s':>9}")


def table_line(s):
    it = s["iterations"]
    return (f"{s['nd']:>4} {s['dofs']:>9} {s['contact_nodes']:>7} {_inner(s)[1]:>9} "
            f"{it['uzawa_mean']:>11.1f} {it['fixed_point']:>4} {s['time_s']['total']:>9.2f}")


def _roundoff_note(s):
    """' (CONVERGED_ROUNDOFF ...)' where a solve (an increment's) stopped at its floor."""
    floors = [e.get("residual_floor") for e in s.get("steps") or []] or \
        [s.get("residual_floor")]
    floors = [f for f in floors if f is not None]
    if not floors:
        return ""
    return (f" ({CONVERGED_ROUNDOFF}: the residual stopped falling at its round-off floor, "
            f"relative {max(floors):.1e}, above the tolerance"
            + (f", in {len(floors)} of {len(s['steps'])} increments" if s.get("steps") else "")
            + ")")


def print_summary(comm, s, outdir=None):
    r = s["residuals"]
    how = {"newton": "solver: newton (the default: semismooth Newton on the whole problem; "
                     "-solver_mode faithful runs the paper's three loops)",
           "faithful": "solver: faithful (the paper's fixed point > Uzawa > APG)",
           "fast": "solver: fast (the paper's loops with semismooth Newton inside; "
                   "-solver_mode faithful: the paper's own)"}
    lines = [header(s), table_line(s),
             *([how[s["solver_mode"]]] if s["mode"] != "linear" and
               s["solver_mode"] in how else []),
             f"mode {s['mode']}, ranks {s['ranks']}, {_inner(s)[2]}, "
             f"energy J(u) = {s['energy']:.10e}, max |u| = {s['max_displacement']:.6e}",
             f"residuals: penetration {r['penetration']:.2e}, complementarity "
             f"{r['complementarity']:.2e}, coulomb {r['coulomb']:.2e}; converged: "
             f"{s['converged']}" + _roundoff_note(s),
             f"loading: {s['loading']}", f"mesh: {s['mesh']}; element {s['element']}" + (
                 " (bodies: " + ", ".join(f"{b} {e}" for b, e in s["body_elements"].items())
                 + ("; a q1 or bbar body's cells are the q2 nodes' mesh)" if s["element"] ==
                    "q2" and {"q1", "bbar"} & set(s["body_elements"].values()) else ")")
                 if set((s.get("body_elements") or {0: s["element"]}).values()) !=
                 {s["element"]} else "")]
    est = s.get("error_estimate")
    if est is not None:
        nds = [int(n) for n in next(iter(est.values()))["levels"]] if est else []
        lines += estimate.lines(est, nds)
    elif s.get("error_estimate_note"):
        lines.append(f"error estimate: {s['error_estimate_note']}")
    if s["skipped"]:
        lines.append("skipped: " + "; ".join(s["skipped"]))
    if outdir:
        lines.append(f"results in {outdir}")
    PETSc.Sys.Print("\n".join(lines), comm=comm)
