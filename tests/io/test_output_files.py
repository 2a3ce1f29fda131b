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

from contact.io import output

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


def _contact(outdir, ranks, *extra):
    cmd = [sys.executable, "-m", "contact", *ARGS, *extra, "-output_dir", str(outdir)]
    if ranks > 1:
        cmd = ["mpirun", "-n", str(ranks), "--oversubscribe", *cmd]
    p = subprocess.run(cmd, cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout + p.stderr
    with open(os.path.join(outdir, "summary.json")) as f:
        assert json.load(f)["ranks"] == ranks           # the run did use that many ranks
    return str(outdir)


#: the runs: the paper's beam (static), a quasi-static one (block_shear: 4 load
#: increments, friction-held, press then shear), and two bodies (punch_on_plate)
SCENES = {"static": (), "quasi": ("-scene", os.path.join(ROOT, "runs", "scenes",
                                                            "block_shear.yaml")),
          "pair": ("-scene", os.path.join(ROOT, "runs", "scenes", "punch_on_plate.yaml"))}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """{(scene, ranks): output directory} of the same runs on 1 and 2 ranks."""
    tmp = tmp_path_factory.mktemp("files")
    return {(k, n): _contact(tmp / f"{k}{n}", n, *extra) for k, extra in SCENES.items()
            for n in (1, 2)}


def _datasets(path):
    """name -> array of every dataset in an HDF5 file."""
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__("/" + name, obj[()])
                     if isinstance(obj, h5py.Dataset) else None)
    return out


#: XDMF AttributeType -> components per point or cell
COMPONENTS = {"Scalar": 1, "Vector": 3, "Tensor6": 6}


@pytest.mark.slow
@skip_in_parallel
@pytest.mark.parametrize("scene", list(SCENES))
@pytest.mark.parametrize("ranks", [1, 2])
def test_xdmf_describes_the_h5_file(runs, scene, ranks):
    """Every DataItem of solution.xdmf: Format HDF, `solution.h5:/path` naming a dataset
    that exists, Dimensions = its shape, NumberType/Precision = its dtype; the grids'
    element and point counts agree with their DataItems (hexahedra and quadrilaterals:
    connectivity into the grid's points; node and cell attributes: one row per point or
    cell, 1, 3 or 6 components); a quasi-static run's grids are temporal collections with
    one grid per increment. Every dataset of the file is described (but the steps' load
    factors), and every field output.py lists is there."""
    outdir = runs[scene, ranks]
    root = ET.parse(os.path.join(outdir, "solution.xdmf")).getroot()
    assert root.tag == "Xdmf"
    grids = root.findall("./Domain/Grid")
    assert [g.get("Name") for g in grids] == ["body", "contact"]   # F > 0: contact grid
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

        steps = f["/steps/load_factor"][()] if "/steps/load_factor" in f else None
        for top in grids:
            if scene == "quasi":
                assert (top.get("GridType"), top.get("CollectionType")) == \
                    ("Collection", "Temporal")
                uniform = top.findall("Grid")
                times = [float(g.find("Time").get("Value")) for g in uniform]
                assert times == list(steps) and times[-1] == 1.0 and len(times) == 4
            else:
                assert top.get("GridType") == "Uniform" and steps is None
                uniform = [top]
            for grid in uniform:
                topo, geom = grid.find("Topology"), grid.find("Geometry")
                assert geom.get("GeometryType") == "XYZ"
                xyz = dataset(geom.find("DataItem"))
                n = xyz.shape[0]
                assert xyz.shape == (n, 3)
                ne, npe = int(topo.get("NumberOfElements")), int(topo.get("NodesPerElement"))
                kind = {"body": "Hexahedron", "contact": "Quadrilateral"}[top.get("Name")]
                assert topo.get("TopologyType") == kind and npe == {"Hexahedron": 8,
                                                                     "Quadrilateral": 4}[kind]
                conn = dataset(topo.find("DataItem"))[()]
                assert conn.shape == (ne, npe) and conn.min() >= 0 and conn.max() < n
                if kind == "Hexahedron":
                    assert np.unique(conn).size == n     # every point in some cell
                for att in grid.findall("Attribute"):
                    a = dataset(att.find("DataItem"))
                    rows = {"Node": n, "Cell": ne}[att.get("Center")]
                    c = COMPONENTS[att.get("AttributeType")]
                    assert a.shape == ((rows,) if c == 1 else (rows, c)), att.get("Name")
        names = set()
        f.visititems(lambda name, obj: names.add("/" + name)
                     if isinstance(obj, h5py.Dataset) else None)
    assert len(checked) == len(list(root.iter("DataItem")))    # every DataItem checked
    assert names - seen <= {"/steps/load_factor"}              # every dataset described
    listed = {"/" + fl.path for fl in output.BODY + output.CONTACT} | \
        {fl.path for fl in output.MESH if not fl.path.startswith("/steps")}
    assert listed <= seen
    if scene == "quasi":                       # each increment before the last has its own
        assert {f"/steps/0003/{fl.path}" for fl in output.BODY + output.CONTACT} <= seen


#: displacements on the contact face: compared at the scale of the body's displacement
#: (the normal one of a pressed face is the loops' tolerance, 1e-6 of it, alone)
LENGTHS = ("normal_displacement", "tangential_displacement", "slip")


def _scale(data, name):
    """The largest magnitude of `name`, or of the displacement of its state for the
    displacements of the contact face."""
    state, group, base = name.rsplit("/", 2)
    if base in LENGTHS:
        return np.abs(data[f"{state}/fields/displacement"]).max()
    return np.abs(data[name]).max()


@skip_in_parallel
@pytest.mark.parametrize("scene", list(SCENES))
def test_two_ranks_write_the_one_rank_file(runs, scene):
    """solution.h5 of `mpirun -n 2` equals the 1-rank file dataset by dataset: the same
    names, shapes and dtypes; the mesh (coordinates, topology) and the contact status
    exactly (canonical node and cell order, coordinates computed from the same box
    formula); the floating-point fields to 1e-10 relative to each dataset's largest
    magnitude (a contact face's displacements: of the body's displacement). Not bitwise:
    the two partitions sum the matrix-vector products, dots and
    norms in other orders, and GAMG's aggregates (the preconditioner of the Newton steps'
    CG) follow the partition. With the CG converged to rounding (-ssn_ksp_rtol 1e-14) the
    two runs then take the same steps and differ by rounding (about 1e-15 measured); with
    the fast mode's own inexact CG (rtol 1e-3) they differ by the loops' tolerances
    instead (4e-8 measured on the pressure), which this bound would rightly reject as
    "not the same computation"."""
    one = _datasets(os.path.join(runs[scene, 1], "solution.h5"))
    two = _datasets(os.path.join(runs[scene, 2], "solution.h5"))
    assert sorted(two) == sorted(one)
    assert {"/mesh/coordinates", "/fields/displacement", "/contact/pressure",
            "/fields/von_mises", "/cells/stress", "/contact/traction"} <= set(one)
    for name, a in one.items():
        b = two[name]
        assert (b.shape, b.dtype) == (a.shape, a.dtype), name
        if name.endswith(("/coordinates", "/topology", "/status", "/load_factor", "/body")) or \
                a.dtype.kind in "iu":
            assert np.array_equal(a, b), name
        elif np.isnan(a).all():              # the error indicator without a coarse level
            assert name.endswith("/error_indicator") and np.isnan(b).all(), name
        else:
            scale = _scale(one, name)
            assert scale > 0, name                           # not a vacuous comparison
            assert np.abs(b - a).max() <= 1e-10 * scale, name
    status = one["/contact/status"]
    assert {1, 2} <= set(np.unique(status))                  # stick and slip both present
    bodies = {"pair": {0.0, 1.0}}.get(scene, {0.0})            # both bodies in one file
    assert set(np.unique(one["/cells/body"])) == bodies


def test_readme_lists_every_dataset():
    """The README's table of solution.h5 is output.dataset_table() (the datasets as
    output.py lists them)."""
    with open(os.path.join(ROOT, "README.md")) as f:
        assert output.dataset_table() in f.read()


def test_an_interrupted_or_failed_write_leaves_no_file(comm, mpi_tmp_path, monkeypatch):
    """All files or none: an interrupt after solution.h5 is complete (under its temporary
    name), or an error on rank 0 while the figures are drawn, leaves an empty directory
    on every rank count (and one clear error on every rank)."""
    from mpi4py import MPI

    from contact.io import figures, report
    from conftest import paper_scene, solve
    pr = solve(paper_scene(nd=1, uzawa_r=1e6, mode="fast"), comm)
    s = report.summary(pr, 0.0)
    dirs = [os.path.join(mpi_tmp_path, d) for d in ("interrupted", "failed")]
    for d in dirs:
        output.prepare_dir(MPI.COMM_WORLD, d)
    real = output.write_hdf5

    def interrupted(*args):
        real(*args)
        raise KeyboardInterrupt

    monkeypatch.setattr(output, "write_hdf5", interrupted)
    with pytest.raises(KeyboardInterrupt):
        output.write_results(pr, dirs[0], s, output.FORMATS)
    monkeypatch.setattr(output, "write_hdf5", real)

    def full(*args):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(figures, "write_all", full)           # rank 0 draws
    with pytest.raises(OSError, match="cannot write results to .*No space left on device"):
        output.write_results(pr, dirs[1], s, output.FORMATS)
    MPI.COMM_WORLD.barrier()
    for d in dirs:
        assert os.listdir(d) == [], d
