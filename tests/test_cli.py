"""The command line end to end: files, keys, console line, errors."""
import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from conftest import ROOT, skip_in_parallel
from mpi4py import MPI
from petsc4py import PETSc

from contact import cli

KEYS = {"scene", "nd", "ranks", "petsc_version", "dofs", "contact_nodes", "iterations",
        "time_s", "energy", "max_displacement", "residuals", "converged"}


def _run(opts):
    o = PETSc.Options()
    for k, v in opts.items():
        o.setValue(k, v)
    return cli.run()


def test_run_writes_results(mpi_tmp_path):
    out = os.path.join(mpi_tmp_path, "out")
    s = _run({"nd": "2", "uzawa_r": "1e6", "output_dir": out})
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
