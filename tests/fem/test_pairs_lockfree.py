"""A body of a lock-free element (bbar, q2p1) beside bodies of another (fem/assembly.py: an
element per group of cells; fem/discretisation.py: capped_groups; multigrid.py:
COARSE_ELEMENT), checked against closed forms and against the one-body path of that
element (no groups: its own assembly, multigrid and, at nu > 0.4, the mixed u-p split):

* the contact patch test at nu = 0.45, a bbar or q2p1 punch on a base of another element
  and the reverse (the rubber the master: its G^T empty in the contact rows), through the
  mixed u-p split: u the linear field of each body, the multiplier p at every slave node, the stress
  -p e_z e_z in every cell, to rounding;
* against one body: a punch (nu = 0.45) pressed and sheared (F = 0.3) under its weight
  on a base held still is the punch alone of that element on the rigid foundation
  (the held master face is the foundation: the pair's gap is the slave's displacement):
  u, multipliers, force and cell stresses to 1e-9, for bbar on q1, q2p1 on q2 and bbar
  beside q2 (its cells the q2 node mesh's: the lone punch at twice the cells);
* the contact stiffness rho = A_nn / w of such a body is that of lambda capped at
  RHO_LAMBDA_CAP mu (fem/discretisation.py), as the one-body path's, and A's own where
  lambda is below the cap;
* runs/scenes/gasket.yaml (rubber between steel): converged in a few Newton steps, the
  gasket in equilibrium between its two pairs;
on 1 and 2 ranks."""
import copy
import os

import numpy as np
import pytest
from conftest import DIRECT, ROOT, fields, gather, needs_direct, rel_err, solve, two_blocks
from petsc4py import PETSc
from test_pairs import P, exact

from contact import options, scene as scenes
from contact.analysis import stress
from contact.fem.discretisation import RHO_LAMBDA_CAP, body_elements
from contact.problem import ContactProblem
from contact.solvers import driver

NU = 0.45
PUSH = (0.002, 0.002, -0.004)


def patch_blocks(slave, base, nu=NU):
    """two_blocks (pressed by p, symmetric) at nu, 3 x 3 base cells under 4 x 4 punch
    cells, 2 through each, with the punch (the slave) of element `slave`."""
    sc = two_blocks(0.3, base_cells=3, punch_cells=4, poisson=nu)
    for b in sc["bodies"].values():
        b["cells"][2] = 2
    sc["bodies"]["punch"]["element"], sc["bodies"]["base"]["element"] = slave, base
    return scenes.validate(sc)


@pytest.mark.parametrize("slave, base", [("bbar", "q1"), ("bbar", "q2"), ("q2p1", "q1"),
                                         ("q2p1", "q2"), ("q1", "bbar"), ("q2", "q2p1")])
def test_patch_lockfree_body(comm, slave, base):
    pr = solve(patch_blocks(slave, base), comm)
    assert pr.converged and pr.disc.body_element == [base, slave]
    xyz, u = gather(pr)[:2]
    off = np.abs(xyz[:, 2] - 0.5) > 1e-12          # (on it the bodies' nodes may meet)
    assert rel_err(u[off], exact(xyz, (1.0, 1.0), NU)[off]) < 1e-8
    lam = pr.cs.local_array(pr.l)
    quadratic = "q2" in (slave, base) or "q2p1" in (slave, base)
    assert pr.comm.tompi4py().allreduce(lam.size) == (81 if quadratic else 25)
    assert np.all(np.abs(lam - P) < 1e-8 * P)
    sig = stress.body_stress(pr)["cell"]
    assert np.abs(sig - [0.0, 0.0, -P, 0.0, 0.0, 0.0]).max(initial=0.0) < 1e-8 * P


def held_base(punch, base, nu=NU):
    """A punch [0, 1]^2 x [0.5, 1] (4 x 4 x 2 cells, element `punch`) pushed down and
    sideways by PUSH on a wider base (3 x 3 x 2 cells, element `base`) whose top and
    bottom are held, F = 0.3, under its weight."""
    sc = two_blocks(friction=0.3, base_cells=3, punch_cells=4, poisson=nu,
                    base=((-0.1, -0.1), (1.1, 1.1)), push=PUSH)
    for b in sc["bodies"].values():
        b["cells"][2] = 2
    sc["bodies"]["punch"]["element"], sc["bodies"]["base"]["element"] = punch, base
    sc["boundary"]["still"] = {"type": "dirichlet", "body": "base", "plane": ["z", 0.5]}
    sc["body_force"] = [0.0, 0.0, -0.01]
    return scenes.validate(sc)


def punch_alone(element, scale, nu=NU):
    """held_base's punch as a one-body scene on the rigid foundation z = 0, its cells
    scale times held_base's."""
    return scenes.validate({
        "name": "punch_alone",
        "mesh": {"type": "box", "lower": [0.0, 0.0, 0.0], "upper": [1.0, 1.0, 0.5],
                 "cells_per_nd": [4, 4, 2], "nd": scale, "element": element},
        "material": {"young": 1.0, "poisson": nu},
        "boundary": {"contact": {"type": "contact", "plane": ["z", 0.0]},
                     "top": {"type": "dirichlet", "plane": ["z", 0.5],
                             "displacement": list(PUSH)}},
        "contact": {"friction": 0.3}, "body_force": [0.0, 0.0, -0.01],
        "solver": {"mode": "newton", "newton_rtol": 1e-12}})


def _by_place(xyz, v):
    return v[np.lexsort(np.round(xyz, 9).T)]


@pytest.mark.parametrize("punch, base, scale", [("bbar", "q1", 1), ("q2p1", "q2", 1),
                                                ("bbar", "q2", 2)])
def test_lockfree_body_is_the_element_alone(comm, punch, base, scale):
    """The punch's u above the interface, its multipliers, the force and its cells'
    stresses: those of the punch alone (its one-body path: at nu = 0.45 the mixed u-p
    split)."""
    two, one = solve(held_base(punch, base), comm), solve(punch_alone(punch, scale), comm)
    assert two.converged and one.converged
    assert two.disc.body_element == [base, punch] and one.element == punch
    (xyz, u), (xyz1, u1) = gather(two)[:2], gather(one)[:2]
    up, up1 = xyz[:, 2] > 0.5 + 1e-12, xyz1[:, 2] > 1e-12
    a, b = _by_place(xyz[up], u[up]), _by_place(xyz1[up1], u1[up1])
    assert a.shape == b.shape and rel_err(a, b) < 1e-9
    lam, lam1 = fields(two)[1], fields(one)[1]
    assert lam.shape == lam1.shape and rel_err(lam, lam1) < 1e-9
    assert abs(two.normal_force() - one.normal_force()) < 1e-9 * abs(one.normal_force())
    s, s1 = _cell_stress(two, 0.5), _cell_stress(one, 0.0)
    assert s.shape == s1.shape and rel_err(s, s1) < 1e-9


def _cell_stress(pr, z):
    """The cell stresses (stress.body_stress; q2p1: its pressure's) of the cells above z,
    every rank's, ordered by their centroids."""
    st = stress.body_stress(pr)
    up = st["centroid"][:, 2] > z
    parts = pr.comm.tompi4py().allgather((st["centroid"][up] - [0.0, 0.0, z], st["cell"][up]))
    return _by_place(*(np.concatenate([p[k] for p in parts]) for k in (0, 1)))


def _contact_rows(pr, d, z):
    """The z entries of the global Vec d at the punch's nodes on z = `z` (its body index
    1), ordered by place, on every rank."""
    X = pr.disc.coordinates.getArray(readonly=True).reshape(-1, 3)
    v = d.getArray(readonly=True).reshape(-1, 3)[:, 2]
    at = (np.abs(X[:, 2] - z) < 1e-12) & (pr.disc.node_bodies() == (1 if pr.disc.bodies else 0))
    parts = pr.comm.tompi4py().allgather((X[at], v[at]))
    return _by_place(np.concatenate([p[0] for p in parts]),
                     np.concatenate([p[1] for p in parts]))


@pytest.mark.parametrize("punch, base", [("bbar", "q1"), ("q2p1", "q2")])
def test_contact_stiffness_of_a_lockfree_body_is_capped(comm, punch, base):
    """The diagonal rho is read from at the punch's slave nodes is the one-body path's
    (lambda = RHO_LAMBDA_CAP mu there) and below A's; at nu = 0.3 (lambda = 1.5 mu) none."""
    two, one = held_base(punch, base), punch_alone(punch, 1)
    pr2, pr1 = solve(two, comm), solve(one, comm)
    d2, d1 = pr2.disc.contact_diagonal, pr1.disc.contact_diagonal
    assert d2 is not None and d1 is not None
    a, b = _contact_rows(pr2, d2, 0.5), _contact_rows(pr1, d1, 0.0)
    assert a.size == b.size > 0 and rel_err(a, b) < 1e-12
    own = pr2.disc.A.getDiagonal()
    assert np.all(a < 0.9 * _contact_rows(pr2, own, 0.5))
    own.destroy()
    assert solve(held_base(punch, base, nu=RHO_LAMBDA_CAP / 5.0), comm).disc \
        .contact_diagonal is None


GASKET = os.path.join(ROOT, "runs", "scenes", "gasket.yaml")


@pytest.mark.parametrize("gasket", ["bbar", "q2p1"])
def test_gasket_between_steel_parts(comm, gasket):
    """runs/scenes/gasket.yaml (a rubber gasket, nu = 0.49, E 2.1e4 times below the steel
    parts around it; two pairs, the gasket the slave of both) at Nd 1: converged (to a
    relative residual of 1e-12) within 8 Newton steps, the forcing terms capped for the
    contrast (driver.EW_CONTRAST; at 0.1 both cases fail this test: checked) at EW_FLOOR,
    and the gasket in equilibrium: the base pushes it up as hard as the flange pushes
    it down, to rounding."""
    sc = scenes.load(GASKET)
    sc["bodies"]["gasket"]["element"] = gasket
    sc["solver"] = {"newton_rtol": 1e-12}
    pr = solve(scenes.validate(sc), comm)
    assert pr.converged and pr.iterations()["inner_total"] <= 8
    assert driver.newton_defaults(None, None, pr.disc) == {"newton_ew_max": "0.0001"}
    seat, squeeze = (stress.pair_results(pr)[k]["normal"]
                     for k in ("seat", "squeeze"))
    assert seat > 0 and abs(seat - squeeze) < 1e-8 * seat


@pytest.mark.parametrize("gasket, nd", [("bbar", 2), ("q2p1", 1)])
def test_frictionless_gasket(comm, gasket, nd):
    """The gasket without friction: converged (to 1e-12) within 6 Newton steps (measured 5
    and 2) and in equilibrium. With the forcing terms capped at EW_CONTRAST = 0.01 alone both stagnate
    (DIVERGED_STAGNATION after 71 and 75 steps: checked); driver.EW_FLOOR converges them."""
    sc = scenes.load(GASKET)
    sc["bodies"]["gasket"]["element"] = gasket
    sc["mesh"]["nd"] = nd
    sc["contact"]["friction"] = 0.0
    sc["solver"] = {"newton_rtol": 1e-12}
    pr = solve(scenes.validate(sc), comm)
    assert pr.converged and pr.iterations()["inner_total"] <= 6
    seat, squeeze = (stress.pair_results(pr)[k]["normal"] for k in ("seat", "squeeze"))
    assert seat > 0 and abs(seat - squeeze) < 1e-8 * seat


def rubber_gasket(element, nd, nu=0.4999):
    """gasket.yaml with its gasket of `element` at nu, Nd nd, solved to 1e-12."""
    sc = scenes.load(GASKET)
    sc["bodies"]["gasket"]["element"] = element
    sc["bodies"]["gasket"]["material"]["poisson"] = nu
    sc["mesh"]["nd"] = nd
    sc["solver"] = {"newton_rtol": 1e-12}
    return scenes.validate(sc)


def _free(disc, M):
    """M (as AIJ) with the clamped rows and columns zeroed (A's and A_g's eliminated rows
    take their own mean diagonals)."""
    M = M.convert("aij") if M.getType().endswith("baij") else M.duplicate(copy=True)
    M.zeroRowsColumns(np.asarray(disc.clamped, dtype=PETSc.IntType), diag=0.0)
    return M


@pytest.mark.parametrize("gasket, nd", [("bbar", 4), ("q2p1", 1)])
def test_split_of_a_rubber_body_condenses_to_its_stiffness(comm, gasket, nd):
    """The mixed u-p split of several bodies (solvers/mixed.py: the rubber gasket's A_g at
    lambda_g = LAMBDA_SPLIT mu beside the steel parts as they are, in the pairs' basis; its
    divergence Gq turned by Z): A_g + Gq^T Cq^-1 R Gq is the discretisation's A~ = Z^T A Z,
    assembled with the full lambda, to rounding (without Z, Gq's condensation is not in
    A~'s basis: its slave unknowns are relative displacements); A_g alone is not (the
    volumetric part is in Gq: measured 3 % and 5 % of A's norm off, which the steel's
    entries dominate)."""
    pr = ContactProblem(rubber_gasket(gasket, nd), comm)
    disc, split = pr.disc, pr.solvers.pressure_split()
    assert split is not None and split.lam_mu > 4e3
    A = _free(disc, disc.A)
    for M, far in ((split.condensed(), False), (split.Ag, True)):
        D = _free(disc, M)
        D.axpy(-1.0, A, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        assert (D.norm() > 0.01 * A.norm()) if far else (D.norm() <= 1e-12 * A.norm())


@needs_direct
@pytest.mark.parametrize("gasket, nd", [("bbar", 4), ("q2p1", 2)])
def test_rubber_gasket_solves_through_the_split(comm, gasket, nd):
    """gasket.yaml at nu = 0.4999 (bbar Nd 4, q2p1 Nd 2: meshes of several levels on 1 and
    2 ranks): the Newton steps' GMRES on the mixed u-p system (the split; its forcing terms
    capped at driver.EW_SPLIT x the contrast's) converges within 9 steps and 300 Krylov
    iterations in all (measured 7 and 205, 6 and 167 on 1 rank, 7 and 199, 6 and 163 on 2;
    on K, -newton_pressure_split off: 7 and 1906, 6 and 1013 with two steps solved
    directly, and 6 and 258, 6 and 307), to the answer of exact Newton steps (LU on K): u,
    the multipliers and both pairs' forces to 1e-7."""
    sc = rubber_gasket(gasket, nd)
    split = solve(sc, comm)
    with options.inserted({"newton_ksp_type": "preonly", "newton_pc_type": "lu",
                           "newton_pc_factor_mat_solver_type": DIRECT}):
        exact_steps = solve(sc, comm)
    assert split.inner.split is not None and exact_steps.inner.split is None
    assert driver.newton_defaults(split.inner.split, None, split.disc)["newton_ew_max"] == \
        "1e-05"
    it = split.iterations()
    assert split.converged and it["inner_total"] <= 9 and it["ksp_total"] <= 300
    (xyz, u), (xyz1, u1) = gather(split)[:2], gather(exact_steps)[:2]
    assert np.array_equal(xyz, xyz1) and rel_err(u, u1) < 1e-7
    assert rel_err(fields(split)[1], fields(exact_steps)[1]) < 1e-7
    for k in ("seat", "squeeze"):
        a, b = (stress.pair_results(p)[k]["normal"] for p in (split, exact_steps))
        assert abs(a - b) < 1e-7 * b


@pytest.mark.parametrize("ratio, cap, steps", [(1e2, "0.001", None), (1e3, "0.0001", 6)])
def test_forcing_terms_scaled_with_contrast(comm, ratio, cap, steps):
    """punch_on_plate.yaml with the punch (the slave) `ratio` times the plate's E: the
    forcing terms capped at driver.EW_RATIO / ratio (at least EW_FLOOR); at 1e3, Nd 2 the
    stiff slave converges within 6 Newton steps (measured 4; 10 at 0.01, 33 at 1e-3)."""
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "punch_on_plate.yaml"))
    plate = sc["bodies"]["plate"]["material"]["young"]
    sc["bodies"]["punch"]["material"]["young"] = ratio * plate
    sc.setdefault("mesh", {})["nd"] = 2 if steps else 1
    pr = solve(scenes.validate(sc), comm)
    assert driver.newton_defaults(None, None, pr.disc) == {"newton_ew_max": cap}
    assert pr.converged and (steps is None or pr.iterations()["inner_total"] <= steps)


def test_auto_element_per_body():
    """auto (a scene's default with bodies) gives a body of nu >= AUTO_LOCKFREE_NU bbar (q1's
    family: the others keep their q1 nodes), the others q1; a scene's element q1 is every
    body's where the body names none; a body's own element wins."""
    sc = scenes.load(GASKET)
    del sc["bodies"]["gasket"]["element"], sc["mesh"]["element"]
    auto = scenes.validate(copy.deepcopy(sc))
    assert auto["mesh"]["element"] == "auto"
    assert body_elements(auto) == ["q1", "bbar", "q1"]
    sc["bodies"]["base"]["element"] = "q2"
    assert body_elements(scenes.validate(copy.deepcopy(sc))) == ["q2", "bbar", "q1"]
    sc["mesh"]["element"] = "q1"
    assert body_elements(scenes.validate(copy.deepcopy(sc))) == ["q2", "q1", "q1"]
    sc["mesh"]["element"] = "auto"
    sc["bodies"]["gasket"]["material"]["poisson"] = 0.3
    assert body_elements(scenes.validate(sc)) == ["q2", "q1", "q1"]


def test_forcing_terms_capped_for_rubber_alone(comm):
    """Bodies of one E (held_base, nu = 0.45: lambda = 9 mu) keep the default forcing terms
    as q1; with a bbar punch (lambda > LAMBDA_SPLIT mu, as the one-body split) they are
    capped."""
    defaults = (driver.newton_defaults(None, None, solve(held_base(p, "q1"), comm).disc)
                for p in ("q1", "bbar"))
    assert list(defaults) == [{}, {"newton_ew_max": "0.01"}]
