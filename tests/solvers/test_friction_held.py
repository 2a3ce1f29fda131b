"""A block held on the foundation by friction alone (no dirichlet part: the translations
along the foundation and the rotation about its normal are free) under pressure p and a
tangential traction q, and loading schedules (per-part ramps).

Closed-form statics of a rigid block: equilibrium iff q <= F p; the run refuses q > F p
with the load step named. Below the limit the discrete Coulomb solution is checked against
the independent conic solver (started from the uniform pressure p, since g = 0 would hold
nothing), and the stick zone shrinks as q approaches F p."""
import copy

import numpy as np
import pytest
from conftest import (block_scene, gather, only_in_parallel, rel_err, skip_in_parallel,
                      solve)
from petsc4py import PETSc
from contact.validation.socp import solve_coulomb
from test_reference import _discrete

from contact import scene as scenes
from contact.scene import SceneError

E, NU, P, F = 1.0e3, 0.3, 2.0, 0.5
TIGHT = dict(uzawa_r=1e4, apg_rtol=1e-12, uzawa_rtol=1e-10, fp_rtol=1e-9)


def sheared(ratio, nd=2, ramps=None, steps=1, **solver):
    """Unit block, contact z = 0, top traction (q, 0, -p) with q = ratio F p; with
    ramps = (press, shear) the two parts of the top traction get these ramps."""
    q = ratio * F * P
    parts = {"contact": {"plane": ["z", 0.0], "type": "contact"}}
    if ramps is None:
        parts["top"] = {"plane": ["z", 1.0], "type": "traction", "traction": [q, 0.0, -P]}
    else:
        parts["press"] = {"plane": ["z", 1.0], "type": "traction",
                          "traction": [0.0, 0.0, -P], "ramp": list(ramps[0])}
        parts["shear"] = {"plane": ["z", 1.0], "type": "traction",
                          "traction": [q, 0.0, 0.0], "ramp": list(ramps[1])}
    sc = block_scene(parts, nd=nd, young=E, poisson=NU, friction=F, **{**TIGHT, **solver})
    sc["loading"]["steps"] = steps
    return scenes.validate(sc)


def bottom_slip(pr):
    """|u_tau| at the nodes of the contact face z = 0 (canonical order)."""
    xyz, u = gather(pr)[:2]
    bot = np.abs(xyz[:, 2]) < 1e-12
    return np.hypot(u[bot, 0], u[bot, 1])


@skip_in_parallel
@pytest.mark.parametrize("mode", ["faithful", "fast"])
def test_below_the_limit_against_conic_solver(mode):
    """q = 0.6 F p: our Coulomb solution equals the conic solver's fixed point."""
    pr = solve(sheared(0.6, mode=mode, ssn_rtol=1e-13), PETSc.COMM_SELF)
    assert pr.friction_held is not None and pr.mode == "coulomb"
    d = _discrete(pr)
    ref = solve_coulomb(F=F, g0=P, tol=1e-11, **d)
    assert rel_err(pr.x.getArray(), ref["u"]) < 1e-6
    assert rel_err(pr.cs.local_array(pr.l), ref["pressure"]) < 1e-6
    assert abs(pr.normal_force() - P) < 1e-8 * P           # N = p * area (statics)


def test_stick_zone_shrinks_toward_the_limit(comm):
    """Stick at low q (no node slips more than 1e-3 of the elastic shear scale q h / G),
    more slip as q -> F p, and the same answer on 1 and 2 ranks (canonical order).

    Full stick at q = 0.2 F p is what the discrete Coulomb problem gives here: a state
    with u_tau = 0 at every contact node is its solution when the reaction R = A u - b of
    that state lies inside the cone (|sigma_tau| <= F g, g >= 0) at every node.
    Pressing alone already asks for |sigma_tau| / g ~ 0.47 at the corners (the bottom
    holds back the Poisson expansion), the shear q = 0.2 F p adds little, so the ratio
    stays below F = 0.5 and every node sticks: u_tau is zero to rounding (< 1e-10 max|u|),
    not merely small. The test checks both halves of that claim: u_tau = 0 and the
    reaction strictly inside the cone. On 2 ranks each load is also solved on COMM_SELF
    and the canonical displacements must agree."""
    from contact.solvers import residuals as res
    G = E / (2 * (1 + NU))
    slips, fractions = [], []
    for ratio in (0.2, 0.6, 0.95):
        sc = sheared(ratio, mode="fast", ssn_rtol=1e-13)
        pr = solve(copy.deepcopy(sc), comm)
        s = bottom_slip(pr)
        scale = ratio * F * P / G
        slips.append(s.mean() / scale)
        fractions.append(np.mean(s > 1e-3 * scale))
        u = gather(pr)[1]
        if ratio == 0.2:                      # full stick, and the stuck state is Coulomb's
            assert s.max() < 1e-10 * np.linalg.norm(u, axis=1).max()
            f = res.contact_fields(pr)
            g = f["R"][:, 2] / f["w"]
            sig_t = np.linalg.norm(f["R"][:, :2], axis=1) / f["w"]
            g_all = np.concatenate(comm.tompi4py().allgather(g))
            ratio_all = np.concatenate(comm.tompi4py().allgather(sig_t / np.where(g > 0, g, 1)))
            assert g_all.size == 9 and (g_all > 0.1 * P).all()        # closed everywhere
            assert ratio_all.max() < 0.98 * F                        # strictly in the cone
        if comm.getSize() > 1:                # the same answer as one process
            ser = gather(solve(sc, PETSc.COMM_SELF))[1]
            assert rel_err(u, ser) < 1e-8
    assert slips[0] < slips[1] < slips[2]
    assert fractions[0] <= fractions[1] <= fractions[2] and fractions[2] > 0
    assert fractions[0] < 1
    assert fractions[0] == 0.0                # every node sticks at q = 0.2 F p


@pytest.mark.parametrize("ratio,steps,where", [(1.2, 1, ""), (1.05, 1, ""),
                                                (1.8, 4, "at load step 3 of 4")])
def test_above_the_limit_slides(comm, ratio, steps, where):
    """q > F p: statics says the block slides; the run refuses (before any solve)."""
    ramps = ((0.0, 0.25), (0.25, 1.0)) if steps > 1 else None
    with pytest.raises(SceneError, match=f"T = .*{where}.*exceeds the friction limit.*slides"):
        solve(sheared(ratio, ramps=ramps, steps=steps), comm)


def test_zero_friction_cannot_hold(comm):
    sc = sheared(0.5)
    sc["contact"]["friction"] = 0.0
    with pytest.raises(SceneError, match="friction could hold.*F = 0"):
        solve(sc, comm)


def test_press_then_shear(comm):
    """Ramps: the press alone for t <= 1/4, then the shear grows to its full value. The
    first step carries no tangential load; each step's normal force is p (statics); the
    part factors are logged; the end state obeys Coulomb's law (residual check)."""
    pr = solve(sheared(0.8, ramps=((0.0, 0.25), (0.25, 1.0)), steps=4, mode="fast",
                       ssn_rtol=1e-13), comm)
    log = pr.step_log
    assert [e["part_factors"] for e in log] == [
        {"press": 1.0, "shear": pytest.approx(s)} for s in (0.0, 1 / 3, 2 / 3, 1.0)]
    assert all(abs(e["normal_force"] - P) < 1e-8 * P for e in log)
    assert max(max(e["residuals"].values()) for e in log) < 1e-6


def test_frictionless_ramps_end_where_the_static_solve_does(comm):
    """Frictionless contact is path-independent: a scene whose load comes in two ramped
    groups (a traction, then a prescribed displacement) ends at the static answer, which
    checks that the group loads sum to the full load."""
    parts = {"sym_x": {"plane": ["x", 0.0], "type": "symmetry"},
             "sym_y": {"plane": ["y", 0.0], "type": "symmetry"},
             "contact": {"plane": ["z", 0.0], "type": "contact"},
             "side": {"plane": ["x", 1.0], "type": "traction", "traction": [-0.5, 0.0, -0.3],
                      "ramp": [0.0, 0.5]},
             "top": {"plane": ["z", 1.0], "type": "dirichlet", "components": ["z"],
                     "displacement": [0.0, 0.0, -0.002], "ramp": [0.5, 1.0]}}
    static = block_scene(parts, nd=2, young=E, poisson=NU, **TIGHT)
    stepped = copy.deepcopy(static)
    stepped["loading"]["steps"] = 3
    ua = gather(solve(static, comm))[1]
    pr = solve(stepped, comm)
    assert rel_err(gather(pr)[1], ua) < 1e-6
    assert [e["part_factors"] for e in pr.step_log] == [
        {"side": pytest.approx(a), "top": pytest.approx(b)}
        for a, b in ((2 / 3, 0.0), (1.0, 1 / 3), (1.0, 1.0))]


@pytest.mark.parametrize("part,msg", [
    ({"type": "traction", "traction": [0, 0, -1], "ramp": [0.5, 0.5]}, "0 <= t0 < t1 <= 1"),
    ({"type": "traction", "traction": [0, 0, -1], "ramp": [0.0, 1.5]}, "0 <= t0 < t1 <= 1"),
    ({"type": "traction", "traction": [0, 0, -1], "ramp": [0.0]}, "list of 2"),
    ({"type": "contact", "ramp": [0.0, 1.0]}, "belongs to traction, pressure and dirichlet"),
])
def test_bad_ramps(part, msg):
    parts = {"clamp": {"plane": ["z", 0.0], "type": "dirichlet"},
             "top": {"plane": ["z", 1.0], **part}}
    with pytest.raises(SceneError, match=msg):
        block_scene(parts)


@only_in_parallel
def test_press_then_shear_same_on_two_ranks(comm):
    """The friction-held, press-then-shear run gives the serial answer on 2 ranks."""
    sc = sheared(0.8, ramps=((0.0, 0.25), (0.25, 1.0)), steps=4, mode="fast",
                 ssn_rtol=1e-13)
    par = gather(solve(copy.deepcopy(sc), comm))[1]
    ser = gather(solve(sc, PETSc.COMM_SELF))[1]
    assert rel_err(par, ser) < 1e-6


def test_block_shear_scene_from_the_command_line(mpi_tmp_path):
    """runs/scenes/block_shear.yaml through the CLI: summary.json says the body is held
    by friction and logs each increment's ramp factors."""
    import json
    import os

    from conftest import ROOT
    from mpi4py import MPI

    from contact import cli
    out = os.path.join(mpi_tmp_path, "out")
    o = PETSc.Options()
    for k, v in {"scene": os.path.join(ROOT, "runs", "scenes", "block_shear.yaml"),
                 "nd": "2", "output_dir": out, "output_formats": "json"}.items():
        o.setValue(k, v)
    s = cli.run()
    assert s["held_by_friction"] and s["converged"] and s["load_steps"] == 4
    if MPI.COMM_WORLD.rank == 0:
        with open(os.path.join(out, "summary.json")) as f:
            js = json.load(f)
        assert [e["part_factors"]["shear"] for e in js["steps"]] == pytest.approx(
            [0.0, 1 / 3, 2 / 3, 1.0])
        assert js["normal_force"] == pytest.approx(2.0, rel=1e-6)


def _shipped(nd, steps, q=None, tall=False):
    """runs/scenes/block_shear.yaml at Nd, with `steps` increments, shear q; tall: the
    block 1 x 1 x 2 (loads on its top, z = 2)."""
    import os

    from conftest import ROOT
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "block_shear.yaml"))
    sc["mesh"]["nd"] = nd
    sc["loading"]["steps"] = steps
    if q is not None:
        sc["boundary"]["shear"]["traction"][0] = q
    if tall:
        sc["mesh"]["upper"][2] = 2.0
        sc["mesh"]["cells_per_nd"][2] = 2
        for part in ("press", "shear"):
            sc["boundary"][part]["plane"][1] = 2.0
    return scenes.validate(sc)


def test_load_continuation_solves_the_same_increment(comm):
    """The shipped scene at Nd = 8 in 2 increments (q = 0.8 F p: the heel lifts, 31 of 81
    nodes stay closed): with the watchdog of 3 steps its second increment stalls (friction
    continuation cannot help a body held by friction alone: it was DIVERGED_STAGNATION),
    the load continuation solves it (s = 1/2, then 1), and the answer is that of another
    path (the default watchdog, no continuation) and a solution's (certified residuals)."""
    from contact import options
    # (with -newton_stall_its 4 the stall comes on 1 to 8 ranks alike; with the default 8
    # it came on 1, 2 and 4, not on 8)
    with options.inserted({"newton_watchdog": "3", "newton_stall_its": "4"}):
        pr = solve(_shipped(8, 2), comm)
    assert pr.converged and pr.inner.load_substeps == [0.5, 1.0]
    assert pr.inner.continuations == 0                 # no friction continuation
    ref = solve(_shipped(8, 2), comm)
    assert ref.converged and ref.inner.load_substeps == []
    assert rel_err(gather(pr)[1], gather(ref)[1]) < 1e-8
    assert max(pr.residuals.values()) < 1e-10


@pytest.mark.parametrize("q,ok", [(0.475, True), (0.55, False)])
def test_tipping(comm, q, ok):
    """A block 1 x 1 x 2 pressed by p = 2 and sheared on its top by q: statics of a rigid
    block puts the load's centre of pressure at x = 1/2 + q H / p (H = 2), inside the face
    (x <= 1) iff q <= 1/2, before it slides (q <= F p = 1). At 0.95 of that limit the heel
    lifts and the default converges; past it the run refuses, naming the point."""
    sc = _shipped(4, 4, q, tall=True)
    if ok:
        pr = solve(sc, comm)
        assert pr.converged and max(pr.residuals.values()) < 1e-9
        assert abs(pr.normal_force() - P) < 1e-8 * P
    else:
        x = 0.5 + q * 2.0 / P
        with pytest.raises(SceneError, match=rf"at load step 4 of 4 .* meets the foundation "
                                             rf"at \({x:g}, 0.5, 0\).*tips over"):
            solve(sc, comm)
