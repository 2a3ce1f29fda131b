"""The files on disk, checked from the files alone: solution.xdmf describes solution.h5
(every DataItem names a dataset that exists, with its shape and number type), and a run
on 2 ranks writes the solution.h5 of a run on 1 rank.

Both runs are `python -m contact` subprocesses (the 2-rank one under mpirun), so these
tests are serial-only: they launch their own ranks."""
import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from conftest import ROOT, skip_in_parallel

#: the fast mode at Nd = 2 (189 dofs), well under a second per run; its Newton steps'
#: linear solves (CG + GAMG) converged to rounding instead of the fast mode's 1e-3, so
#: that two partitions differ by rounding only (see the test)
ARGS = ["-nd", "2", "-solver_mode", "fast", "-ssn_ksp_rtol", "1e-14"]
#: XDMF NumberType -> NumPy dtype kind; Char/UChar are one byte (XDMF's default: Float, 4)
KINDS = {"Float": "f", "Int": "i", "UInt": "u", "Char": "i", "UChar": "u"}


def _env():
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    for k in [k for k in env if k.startswith(("OMPI_COMM_WORLD", "PMIX_", "OMPI_MCA_orte"))]:
        env.pop(k)
    return env


def _contact(outdir, ranks):
    cmd = [sys.executable, "-m", "contact", *ARGS, "-output_dir", str(outdir)]
    if ranks > 1:
        cmd = ["mpirun", "-n", str(ranks), "--oversubscribe", *cmd]
    p = subprocess.run(cmd, cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout + p.stderr
    with open(os.path.join(outdir, "summary.json")) as f:
        assert json.load(f)["ranks"] == ranks           # the run did use that many ranks
    return str(outdir)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """{ranks: output directory} of the same run on 1 and 2 ranks."""
    tmp = tmp_path_factory.mktemp("files")
    return {n: _contact(tmp / f"D{n}", n) for n in (1, 2)}


def _datasets(path):
    """name -> array of every dataset in an HDF5 file."""
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__("/" + name, obj[()])
                     if isinstance(obj, h5py.Dataset) else None)
    return out


@skip_in_parallel
@pytest.mark.parametrize("ranks", [1, 2])
def test_xdmf_describes_the_h5_file(runs, ranks):
    """Every DataItem of solution.xdmf: Format HDF, `solution.h5:/path` naming a dataset
    that exists, Dimensions = its shape, NumberType/Precision = its dtype; the grids'
    element and point counts agree with their DataItems."""
    outdir = runs[ranks]
    root = ET.parse(os.path.join(outdir, "solution.xdmf")).getroot()
    assert root.tag == "Xdmf"
    grids = root.findall("./Domain/Grid")
    assert [g.get("Name") for g in grids] == ["body", "contact"]   # F = 0.3: contact grid
    seen, checked = set(), []
    with h5py.File(os.path.join(outdir, "solution.h5"), "r") as f:
        def dataset(item):
            assert item.get("Format") == "HDF"
            fname, _, path = item.text.strip().partition(":")
            assert fname == "solution.h5" and path.startswith("/")
            assert path in f and isinstance(f[path], h5py.Dataset), path
            ds = f[path]
            dims = tuple(int(d) for d in item.get("Dimensions").split())
            assert dims == ds.shape, path
            kind = KINDS[item.get("NumberType", "Float")]
            precision = int(item.get("Precision", "1" if "Char" in item.get(
                "NumberType", "") else "4"))
            assert (ds.dtype.kind, ds.dtype.itemsize) == (kind, precision), \
                f"{path}: {ds.dtype} described as {item.get('NumberType')} {precision}"
            seen.add(path)
            checked.append(item)
            return ds

        for grid in grids:
            topo, geom = grid.find("Topology"), grid.find("Geometry")
            assert geom.get("GeometryType") == "XYZ"
            xyz = dataset(geom.find("DataItem"))
            n = xyz.shape[0]
            assert xyz.shape == (n, 3)
            ne, npe = int(topo.get("NumberOfElements")), int(topo.get("NodesPerElement"))
            item = topo.find("DataItem")
            if item is not None:                     # hexahedra: connectivity into points
                conn = dataset(item)[()]
                assert topo.get("TopologyType") == "Hexahedron" and npe == 8
                assert conn.shape == (ne, npe) and conn.min() >= 0 and conn.max() < n
                assert np.unique(conn).size == n     # every point in some cell
            else:                                    # one point per element
                assert topo.get("TopologyType") == "Polyvertex" and (ne, npe) == (n, 1)
            for att in grid.findall("Attribute"):
                assert att.get("Center") == "Node"
                a = dataset(att.find("DataItem"))
                assert a.shape == ((n, 3) if att.get("AttributeType") == "Vector" else (n,))
    assert len(checked) == len(list(root.iter("DataItem")))    # every DataItem checked
    assert {"/mesh/coordinates", "/mesh/topology", "/fields/displacement",
            "/contact/coordinates", "/contact/pressure", "/contact/slip",
            "/contact/status"} <= seen


@skip_in_parallel
def test_two_ranks_write_the_one_rank_file(runs):
    """solution.h5 of `mpirun -n 2` equals the 1-rank file dataset by dataset: the same
    names, shapes and dtypes; the mesh (coordinates, topology) and the contact status
    exactly (canonical node and cell order, coordinates computed from the same box
    formula); the floating-point fields to 1e-10 relative to each dataset's largest
    magnitude. Not bitwise: the two partitions sum the matrix-vector products, dots and
    norms in other orders, and GAMG's aggregates (the preconditioner of the Newton steps'
    CG) follow the partition. With the CG converged to rounding (-ssn_ksp_rtol 1e-14) the
    two runs then take the same steps and differ by rounding (about 1e-15 measured); with
    the fast mode's own inexact CG (rtol 1e-3) they differ by the loops' tolerances
    instead (4e-8 measured on the pressure), which this bound would rightly reject as
    "not the same computation"."""
    one = _datasets(os.path.join(runs[1], "solution.h5"))
    two = _datasets(os.path.join(runs[2], "solution.h5"))
    assert sorted(two) == sorted(one)
    assert {"/mesh/coordinates", "/fields/displacement", "/contact/pressure"} <= set(one)
    for name, a in one.items():
        b = two[name]
        assert (b.shape, b.dtype) == (a.shape, a.dtype), name
        if name in ("/mesh/coordinates", "/mesh/topology", "/contact/coordinates",
                    "/contact/status") or a.dtype.kind in "iu":
            assert np.array_equal(a, b), name
        else:
            scale = np.abs(a).max()
            assert scale > 0, name                           # not a vacuous comparison
            assert np.abs(b - a).max() <= 1e-10 * scale, name
    status = one["/contact/status"]
    assert {1, 2} <= set(np.unique(status))                  # stick and slip both present
