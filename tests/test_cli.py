"""The command line end to end: files, keys, console line, errors."""
import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from conftest import PAPER, ROOT, gather, paper_scene, rel_err, skip_in_parallel, solve
from mpi4py import MPI
from petsc4py import PETSc

from contact import cli

#: VTK hexahedron corners on the reference cube [-1, 1]^3 (the order /mesh/topology uses)
VTK_HEX = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                    [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float)
#: the 6 faces of a VTK hexahedron (corner indices, cyclic)
VTK_FACES = ((0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7))

KEYS = {"scene", "nd", "ranks", "petsc_version", "dofs", "contact_nodes", "iterations",
        "time_s", "energy", "max_displacement", "residuals", "converged"}


def _run(opts):
    o = PETSc.Options()
    for k, v in opts.items():
        o.setValue(k, v)
    return cli.run()


def test_run_writes_results(mpi_tmp_path):
    out = os.path.join(mpi_tmp_path, "out")
    s = _run({"nd": "2", "output_dir": out})          # the default solver (newton)
    nd = 2
    assert s["dofs"] == 3 * (3 * nd + 1) * (nd + 1) ** 2          # n_p as the paper counts
    assert s["contact_nodes"] == (3 * nd + 1) * (nd + 1)          # n_d
    assert s["ranks"] == MPI.COMM_WORLD.size and s["converged"]
    if MPI.COMM_WORLD.rank == 0:
        with open(os.path.join(out, "summary.json")) as f:
            js = json.load(f)
        assert KEYS <= set(js)
        assert set(js["iterations"]) == {"fixed_point", "uzawa_total", "uzawa_mean",
                                         "apg_first", "apg_total", "inner", "inner_first",
                                         "inner_total", "ksp_total"}
        assert set(js["residuals"]) == {"penetration", "complementarity", "coulomb"}
        with h5py.File(os.path.join(out, "solution.h5")) as f:
            n = (3 * nd + 1) * (nd + 1) ** 2
            assert f["/mesh/coordinates"].shape == (n, 3)
            assert f["/fields/displacement"].shape == (n, 3)
            m = f["/contact/pressure"].shape[0]
            assert f["/contact/coordinates"].shape == (m, 3)
            assert np.all(f["/contact/pressure"][()] >= 0)
            assert set(np.unique(f["/contact/status"][()])) <= {0, 1, 2}
            u = f["/fields/displacement"][()]
            assert np.max(np.linalg.norm(u, axis=1)) == pytest.approx(js["max_displacement"])
        ET.parse(os.path.join(out, "solution.xdmf"))
        assert not [f for f in os.listdir(out) if ".tmp" in f]
    _check_against_independent(out)


def _strain_energy(xyz, cells, u, lam, mu):
    """1/2 a(u, u) = int 1/2 sigma(u) : eps(u) over the Q1 mesh, 2x2x2 Gauss, from the
    file's arrays alone (cells in VTK order); also the Jacobian determinants (c, 8)."""
    g = 1.0 / np.sqrt(3.0)
    gp = np.array([[a, b, c] for a in (-g, g) for b in (-g, g) for c in (-g, g)])
    fac = 1.0 + gp[:, None, :] * VTK_HEX[None]                    # (gp, a, 3)
    dN = np.stack([VTK_HEX[None, :, i] * np.prod(np.delete(fac, i, axis=2), axis=2) / 8
                   for i in range(3)], axis=-1)                   # dN_a/dxi_i (gp, a, 3)
    J = np.einsum("gai,caj->cgij", dN, xyz[cells])                # dx_j/dxi_i
    det = np.linalg.det(J)
    dNdx = np.einsum("cgij,gaj->cgai", np.linalg.inv(J), dN)
    grad = np.einsum("cgai,caj->cgij", dNdx, u[cells])            # du_j/dx_i
    eps = 0.5 * (grad + np.swapaxes(grad, -1, -2))
    tr = np.trace(eps, axis1=-2, axis2=-1)
    density = 0.5 * lam * tr ** 2 + mu * np.einsum("cgij,cgij->cg", eps, eps)
    return float((density * det).sum()), det


def _plane_faces(xyz, cells, axis, value):
    """Corner indices (f, 4) of the cell faces lying on the plane x_axis = value."""
    faces = cells[:, VTK_FACES].reshape(-1, 4)
    return faces[np.all(np.abs(xyz[faces, axis] - value) < 1e-12, axis=1)]


def _parallelogram_area(xyz, faces):
    X = xyz[faces]
    return 0.5 * np.linalg.norm(np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 1]), axis=1)


def _check_against_independent(out):
    """solution.h5 against what is not the written vector: (1) its displacement equals
    problem.displacement() of a separate in-process solve (COMM_SELF, canonical order);
    (2) the pressure times nodal weights computed here from /mesh (face area / 4 per corner
    on the contact plane z = 0) sums to summary.json's normal_force; (3) the energy
    J(u) = 1/2 a(u,u) - b(u) + sum F g w |u_tau| recomputed here from the file's mesh and
    fields and the scene file's material, tractions and F (own Q1 strain energy, own load
    integrals) equals summary.json's energy."""
    import yaml
    rank0 = MPI.COMM_WORLD.rank == 0
    pr = solve(paper_scene(nd=2, mode="newton"), PETSc.COMM_SELF)
    assert pr.converged
    xyz_ref, u_ref = gather(pr)[:2]
    if not rank0:
        return
    with open(os.path.join(out, "summary.json")) as f:
        js = json.load(f)
    with h5py.File(os.path.join(out, "solution.h5")) as f:
        xyz, cells, u = (f[k][()] for k in ("/mesh/coordinates", "/mesh/topology",
                                             "/fields/displacement"))
        cxyz, pressure = f["/contact/coordinates"][()], f["/contact/pressure"][()]
    # (1) the same displacement as a separate solve; one rank: the same operations in the
    # same order (bitwise today; 1e-12 allows a harmless reordering); two ranks: other
    # summation orders, and the loops (tolerance 1e-6) may stop an iteration apart
    assert np.array_equal(xyz, xyz_ref)
    assert rel_err(u, u_ref) < (1e-12 if MPI.COMM_WORLD.size == 1 else 1e-6)
    # nodal weights of the contact face z = 0, from the file's mesh alone
    faces = _plane_faces(xyz, cells, 2, 0.0)
    assert faces.shape[0] == 6 * 2                         # the 6 x 2 cells under the beam
    w = np.zeros(len(xyz))
    np.add.at(w, faces, np.repeat(_parallelogram_area(xyz, faces)[:, None] / 4, 4, axis=1))
    assert w.sum() == pytest.approx(3.0, rel=1e-14)        # the area of the contact face
    index = {tuple(p): i for i, p in enumerate(xyz)}
    rows = np.array([index[tuple(p)] for p in cxyz])       # contact nodes in the mesh
    assert np.all(cxyz[:, 2] == 0.0) and np.all(cxyz[:, 0] > 0.0)   # not the clamped x = 0
    assert len(rows) == 6 * 3
    # (2) pressure x weight sums to the normal force
    assert float(pressure @ w[rows]) == pytest.approx(js["normal_force"], rel=1e-10)
    # (3) the energy from the file's fields
    with open(PAPER) as f:
        scene = yaml.safe_load(f)
    # (PyYAML reads 21.19e4, exponent without a sign, as a string: float() it)
    E, nu = float(scene["material"]["young"]), float(scene["material"]["poisson"])
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    half_a, det = _strain_energy(xyz, cells, u, lam, mu)
    assert np.all(det > 0)                                  # topology in VTK order
    load = 0.0                      # b(u) = sum over traction faces of int t . u ds
    for part in scene["boundary"].values():
        if part["type"] != "traction":
            continue
        axis, value = "xyz".index(part["plane"][0]), float(part["plane"][1])
        fc = _plane_faces(xyz, cells, axis, value)          # u bilinear: exact
        t = np.array(part["traction"], dtype=float)
        load += float(np.sum(_parallelogram_area(xyz, fc) * (u[fc].mean(axis=1) @ t)))
    slip = np.linalg.norm(u[rows, :2], axis=1)
    friction = float(scene["contact"]["friction"]) * float(np.sum(pressure * w[rows] * slip))
    J = half_a - load + friction
    assert J < 0 and friction > 0
    # the file holds the final multiplier l, summary.json's energy the g of the final
    # solve: equal to the fixed point's tolerance (1e-6) in the friction term
    assert J == pytest.approx(js["energy"], rel=1e-6)


def _cli(args, **kw):
    env = dict(os.environ)
    env.pop("OMPI_COMM_WORLD_SIZE", None)
    return subprocess.run([sys.executable, "-m", "contact"] + args, cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=120, **kw)


@skip_in_parallel
def test_cli_prints_table_line(tmp_path):
    p = _cli(["-nd", "1", "-uzawa_r", "1e6", "-output_dir", str(tmp_path)])
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    header = next(i for i, l in enumerate(lines) if l.split()[:3] == ["Nd", "n_p", "n_d"])
    assert lines[header + 1].split()[:3] == ["1", "48", "8"]


@skip_in_parallel
@pytest.mark.parametrize("args,msg", [
    (["-young", "-5"], "Young's modulus"),
    (["-poisson", "0.5"], "Poisson ratio"),
    (["-nd", "0"], "nd must be"),
    (["-scene", "/nonexistent.yaml"], "cannot read scene file"),
])
def test_cli_bad_input_one_line_nonzero_exit(tmp_path, args, msg):
    p = _cli(args + ["-output_dir", str(tmp_path / "o")])
    assert p.returncode != 0
    assert msg in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert "Traceback" not in p.stderr
    assert not (tmp_path / "o").exists() or not os.listdir(tmp_path / "o")
