"""Stress and contact tractions (contact/analysis/stress.py) against closed forms, and the
resultants against the statics of bodies held only by the foundation."""
import os

import numpy as np
from conftest import ROOT, block_scene, only_in_parallel, paper_scene, solve
from petsc4py import PETSc
from test_contact_closed_form import PRESSED
from test_friction_held import F as F_HELD, P as P_HELD, sheared

from contact import fem, scene as scenes
from contact.io import layout
from contact.analysis import stress
from contact.mesh import HEX_REF

E, NU, P = 1.0e3, 0.3, 2.0
#: Voigt index -> tensor index, written out (stress.COMPONENTS: xx, yy, zz, xy, yz, xz)
VOIGT = [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)]
#: the fast mode's loops converged to rounding (closed forms are met to ~1e-12)
EXACT = dict(mode="fast", ssn_rtol=1e-14, uzawa_rtol=1e-13)


def _hooke(eps, lam, mu):
    return lam * np.trace(eps) * np.eye(3) + 2.0 * mu * eps


def _von_mises(sig):
    """sqrt(3/2 s:s), s the deviator (the other common form of the formula)."""
    s = sig - np.trace(sig) / 3.0 * np.eye(3)
    return np.sqrt(1.5 * np.sum(s * s))


def _tight_options():
    opts = PETSc.Options()
    for k, v in (("elastic_ksp_rtol", "1e-14"), ("ssn_ksp_rtol", "1e-14"),
                 ("uzawa_inexact", "0"), ("fp_inexact", "0")):
        opts.setValue(k, v)


def test_linear_field_on_skewed_cells_gives_hookes_stress():
    """u = G x on affine (skewed, stretched) hexahedra: the strain is sym G everywhere, so
    each cell's mean stress is Hooke's law of sym G, whatever the cell's shape."""
    rng = np.random.default_rng(3)
    lam, mu = fem.lame(E, NU)
    A = np.eye(3) + 0.3 * rng.standard_normal((4, 3, 3))         # 4 affine maps, det > 0
    A[np.linalg.det(A) < 0, :, 0] *= -1.0
    X = np.einsum("cij,aj->cai", A, HEX_REF) + rng.standard_normal((4, 1, 3))
    G = rng.standard_normal((3, 3)) * 1e-3
    s, vol = stress.cell_stress(X, X @ G.T, lam, mu)
    sig = _hooke(0.5 * (G + G.T), lam, mu)
    want = np.array([sig[i, j] for i, j in VOIGT])
    assert np.abs(s - want).max() <= 1e-12 * np.abs(want).max()
    assert np.allclose(vol, 8.0 * np.abs(np.linalg.det(A)), rtol=1e-13)
    assert abs(stress.von_mises(s[0]) - _von_mises(sig)) <= 1e-12 * _von_mises(sig)


def test_uniaxial_bar(comm):
    """A bar (2 x 1 x 1) on three symmetry planes pulled by p on its end: sigma_xx = p, the
    other components 0, von Mises p, in every cell and at every node."""
    _tight_options()
    parts = {"sym_x": {"plane": ["x", 0.0], "type": "symmetry"},
             "sym_y": {"plane": ["y", 0.0], "type": "symmetry"},
             "sym_z": {"plane": ["z", 0.0], "type": "symmetry"},
             "end": {"plane": ["x", 2.0], "type": "traction", "traction": [P, 0.0, 0.0]}}
    pr = solve(block_scene(parts, nd=2, young=E, poisson=NU, size=(2.0, 1.0, 1.0)), comm)
    assert pr.mode == "linear"
    body = stress.body_stress(pr)
    want = np.array([P, 0, 0, 0, 0, 0])
    for s, vm in ((body["cell"], body["cell_von_mises"]),
                  (body["nodal"], body["nodal_von_mises"])):
        assert s.shape[0] > 0
        assert np.abs(s - want).max() <= 1e-8 * P
        assert np.abs(vm - P).max() <= 1e-8 * P


def test_pressed_block_stress_and_contact_tractions(comm):
    """A block on the frictionless foundation under pressure p on top (symmetry planes
    x = 0, y = 0): sigma_zz = -p and nothing else; the traction of the foundation is
    (0, 0, p) at every contact node; the resultant is p x area, all of it in contact."""
    _tight_options()
    pr = solve(block_scene(PRESSED, nd=2, young=E, poisson=NU, uzawa_r=1e4, **EXACT), comm)
    st = stress.final(pr)
    body, c = st["body"], st["contact"]
    want = np.array([0, 0, -P, 0, 0, 0])
    assert np.abs(body["cell"] - want).max() <= 1e-8 * P
    assert np.abs(body["nodal"] - want).max() <= 1e-8 * P
    assert np.abs(body["nodal_von_mises"] - P).max() <= 1e-8 * P
    assert np.abs(c["traction"] - [0.0, 0.0, P]).max(initial=0.0) <= 1e-8 * P
    assert np.abs(c["normal_traction"] - P).max(initial=0.0) <= 1e-8 * P
    assert np.abs(c["pressure"] - P).max(initial=0.0) <= 1e-8 * P
    assert np.all(c["status"] > 0) and np.all(c["friction_use"] == 0.0)    # F = 0
    r = stress.summary(pr)
    res = r["contact_result"]
    assert abs(res["normal"] - P * 1.0) <= 1e-8 * P                  # area 1
    assert res["tangential"] <= 1e-8 * P
    assert abs(res["area"]["contact"] - 1.0) < 1e-12 and res["area"]["separated"] == 0.0
    assert abs(r["von_mises_max"]["value"] - P) <= 1e-8 * P


def test_friction_held_block_resultant_is_the_applied_load(comm):
    """A block held by friction alone (no dirichlet part), pressed by p and sheared by
    q = 0.6 F p on its unit top: the foundation carries the whole load, so the resultant
    contact force is (-q, 0, p): N = p, T = q."""
    _tight_options()
    pr = solve(sheared(0.6, mode="fast", ssn_rtol=1e-13), comm)
    res = stress.summary(pr)["contact_result"]
    q = 0.6 * F_HELD * P_HELD
    assert abs(res["normal"] - P_HELD) <= 1e-8 * P_HELD
    assert abs(res["tangential"] - q) <= 1e-7 * P_HELD
    assert np.allclose(res["force"], [-q, 0.0, P_HELD], atol=1e-7 * P_HELD)
    a = res["area"]
    assert a["stick"] > 0 and abs(a["contact"] + a["separated"] - 1.0) < 1e-12


def test_tilted_foundation_tractions_are_in_xyz(comm):
    """runs/scenes/block_incline.yaml: a unit block under its weight (0, 0, -1) on a plane
    tilted 20 degrees: the contact resultant is (0, 0, 1) in x, y, z (it holds the whole
    weight), N = cos 20, T = sin 20; each traction's normal part is the pressure g."""
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "block_incline.yaml"))
    sc["mesh"]["nd"] = 2
    sc["solver"].update(ssn_rtol=1e-13, uzawa_rtol=1e-12)
    _tight_options()
    pr = solve(scenes.validate(sc), comm)
    assert pr.frame is not None                                      # the rotated basis
    res = stress.summary(pr)["contact_result"]
    th = np.radians(20.0)
    assert np.allclose(res["force"], [0.0, 0.0, 1.0], atol=1e-7)
    assert abs(res["normal"] - np.cos(th)) < 1e-7 and abs(res["tangential"] - np.sin(th)) < 1e-7
    c = stress.final(pr)["contact"]
    n = np.asarray(pr.normal) / np.linalg.norm(pr.normal)
    assert np.allclose(c["traction"] @ n, c["normal_traction"], rtol=0, atol=1e-12)


def _canonical(comm, xyz, *values):
    """(xyz, values...) of all ranks, sorted by (z, y, x)."""
    mpi = comm.tompi4py()
    xyz = np.concatenate(mpi.allgather(xyz))
    order = layout.canonical_order(xyz)
    return [xyz[order]] + [np.concatenate(mpi.allgather(v))[order] for v in values]


@only_in_parallel
def test_von_mises_of_the_paper_beam_equal_on_one_and_two_ranks():
    """Nodal and cell von Mises stress of the paper's beam (Nd = 2), 2 ranks against each
    rank's serial solve: equal to rounding."""
    _tight_options()
    sc = paper_scene(nd=2, uzawa_r=1e6, **EXACT)
    out = []
    for comm in (PETSc.COMM_WORLD, PETSc.COMM_SELF):
        pr = solve(sc, comm)
        b = stress.final(pr)["body"]
        xyz = pr.coordinates.getArray(readonly=True).reshape(-1, 3)
        nodes = _canonical(comm, xyz, b["nodal_von_mises"])
        cells = _canonical(comm, b["centroid"], b["cell_von_mises"])
        out.append((nodes, cells, stress.summary(pr)["von_mises_max"]["value"]))
    (n2, c2, m2), (n1, c1, m1) = out
    assert np.array_equal(n2[0], n1[0]) and np.allclose(c2[0], c1[0], rtol=0, atol=1e-14)
    for a, b in ((n2[1], n1[1]), (c2[1], c1[1])):
        assert a.size > 0 and np.abs(a - b).max() <= 1e-10 * np.abs(b).max()
    assert abs(m2 - m1) <= 1e-10 * m1
