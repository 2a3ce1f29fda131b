"""The figures of a run (-output_formats ...,png; contact/io/figures.py): they exist, are
PNG images, and are not blank: many distinct colours, and the contact map shows the
colours of the statuses the solution has. For the paper's beam, a gmsh scene (Hertz) and
a quasi-static scene (block_shear), on 1 and 2 ranks (rank 0 draws what was gathered)."""
import os

import numpy as np
import pytest
from conftest import ROOT, paper_scene, solve
from mpi4py import MPI

from contact.io import figures, output, report
from contact import scene as scenes


def _scene(name):
    if name == "paper_beam":
        return paper_scene(nd=2, uzawa_r=1e6, mode="fast")
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", f"{name}.yaml"))
    sc.setdefault("mesh", {})["nd"] = 2
    return scenes.validate(sc)


def _colours(path):
    import matplotlib.image as mpimg
    img = mpimg.imread(path)
    rgb = (np.round(img[..., :3] * 255)).astype(np.int64).reshape(-1, 3)
    return np.unique(rgb @ [65536, 256, 1]), rgb


EXPECTED = {"paper_beam": ["contact_status.png", "contact_pressure.png",
                           "contact_displacement.png", "body_von_mises.png"],
            "hertz": ["contact_status.png", "contact_pressure.png",
                      "contact_displacement.png", "body_von_mises.png"],
            "block_shear": ["contact_status.png", "contact_pressure.png",
                            "contact_displacement.png", "body_von_mises.png",
                            "load_path.png"]}


@pytest.mark.parametrize("name", list(EXPECTED))
def test_figures_exist_and_are_not_blank(comm, mpi_tmp_path, name):
    pr = solve(_scene(name), comm)
    s = report.summary(pr, 0.0)
    output.write_results(pr, mpi_tmp_path, s, ("png",))
    MPI.COMM_WORLD.barrier()
    files = sorted(f for f in os.listdir(mpi_tmp_path) if not f.startswith("."))
    assert files == sorted(EXPECTED[name])                 # no temporary left behind
    for f in files:
        path = os.path.join(mpi_tmp_path, f)
        with open(path, "rb") as fh:
            assert fh.read(8) == b"\x89PNG\r\n\x1a\n", f
        distinct, rgb = _colours(path)
        assert len(distinct) > 200, (f, len(distinct))     # a drawing, not a blank page
        assert np.mean(np.all(rgb > 245, axis=1)) < 0.97, f  # not all white
    # the contact map paints each status the solution has, in its colour
    _, rgb = _colours(os.path.join(mpi_tmp_path, "contact_status.png"))
    c = output.gather_contact(pr)
    if MPI.COMM_WORLD.rank == 0:
        frictionless = not np.any(c["F"] > 0)
        for k in np.unique(c["status"]):
            col = figures.STATUS_COLORS[k] if not (frictionless and k) else "#1a9641"
            want = np.array([int(col[i:i + 2], 16) for i in (1, 3, 5)])
            share = np.mean(np.all(np.abs(rgb - want) <= 2, axis=1))
            assert share > 0.002, (name, k, share)


def test_each_contact_part_drawn_apart(comm, mpi_tmp_path):
    """Several bodies (the stack: a gasket pressed by the punch above and on the base below,
    both its faces slaves at the same x, y): one set of contact figures per part, each with
    the nodes of its own face only (on its plane) and its own pair's resultant; drawn
    together the two faces overlapped and the resultants cancelled (N = 9.5e-11)."""
    from contact.io import layout
    pr = solve(_scene("stack_three_blocks"), comm)
    s = report.summary(pr, 0.0)
    data = layout.figure_data(pr, s)
    output.write_results(pr, mpi_tmp_path, s, ("png",))
    MPI.COMM_WORLD.barrier()
    files = sorted(f for f in os.listdir(mpi_tmp_path) if f.startswith("contact_"))
    parts = [n for n, p in pr.scene["boundary"].items() if p["type"] == "contact"]
    assert len(parts) == 2
    assert files == sorted(f"{k}_{n}.png" for k in ("contact_status", "contact_pressure",
                                                   "contact_displacement") for n in parts)
    if MPI.COMM_WORLD.rank:
        return
    for k, part in enumerate(data["contact_parts"]):
        d = figures._part(data, k, part)
        plane = pr.scene["boundary"][part["name"]]["plane"]
        z = d["contact"]["coordinates"][:, "xyz".index(plane[0])]
        assert np.all(np.abs(z - plane[1]) < 1e-12) and z.size >= s["contact_pairs"][
            part["name"]]["slave_nodes"]
        assert d["contact_result"]["normal"] == s["contact_pairs"][part["name"]][
            "contact_result"]["normal"] > 0
