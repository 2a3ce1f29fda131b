"""A scene computes only what it needs, and the run says what it skipped."""
import json
import os
import subprocess
import sys

import pytest
from conftest import ROOT, paper_scene, skip_in_parallel, solve

from contact.io import output
from contact import scene as scenes
from contact.solvers.paper.uzawa import Uzawa

PY = sys.executable


def test_no_contact_part_is_one_ksp_solve(comm, monkeypatch):
    """Without a contact part the Uzawa loop is never entered."""
    def refuse(*a, **k):
        raise AssertionError("Uzawa entered")
    monkeypatch.setattr(Uzawa, "solve", refuse)
    sc = paper_scene(nd=1)
    del sc["boundary"]["contact"]
    sc["boundary"]["bottom"] = {"plane": ["z", 0.0], "type": "dirichlet"}
    sc["loading"]["steps"] = 3
    pr = solve(scenes.validate(sc), comm)
    assert pr.mode == "linear" and pr.uzawa is None and pr.fp is None
    assert pr.load_steps == 1 and pr.iterations()["ksp_total"] > 0
    text = "; ".join(pr.skipped)
    assert "one KSP solve" in text and "load steps" in text
    assert "body-force assembly" in text and "gmsh" in text


def test_frictionless_scene_skips_the_fixed_point(comm):
    sc = paper_scene(nd=1, uzawa_r=1e6)
    sc["contact"]["friction"] = 0.0
    pr = solve(sc, comm)
    assert pr.fp is None and pr.mode == "frictionless"
    assert any("fixed-point loop and prox" in s for s in pr.skipped)
    assert pr.iterations()["fixed_point"] == 0


def test_body_force_is_assembled_only_when_given(comm):
    sc = paper_scene(nd=1, uzawa_r=1e6)
    sc["body_force"] = [0.0, 0.0, -1.0]
    pr = solve(sc, comm)
    assert not any("body-force" in s for s in pr.skipped)


def test_output_formats():
    assert output.parse_formats("h5,xdmf,json") == ("h5", "xdmf", "json")
    assert output.parse_formats("none") == ()
    with pytest.raises(ValueError, match="xdmf describes the h5"):
        output.parse_formats("xdmf,json")
    with pytest.raises(ValueError, match="unknown format 'vtk'"):
        output.parse_formats("json,vtk")


@skip_in_parallel
def test_box_run_never_imports_gmsh_and_writes_only_what_was_asked(tmp_path):
    """A box scene: gmsh is not imported; -output_formats json writes summary.json only."""
    code = ("import sys, petsc4py; petsc4py.init(sys.argv); from contact import cli; "
            "s = cli.run(); assert 'gmsh' not in sys.modules, 'gmsh imported'; "
            "print('SKIPPED', s['skipped'])")
    env = dict(os.environ, PYTHONPATH=ROOT)
    r = subprocess.run([PY, "-c", code, "-nd", "1", "-output_formats", "json",
                        "-output_dir", str(tmp_path), "-uzawa_r", "1e6"],
                       capture_output=True, text=True, cwd=ROOT, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    assert sorted(os.listdir(tmp_path)) == ["summary.json"]
    s = json.load(open(tmp_path / "summary.json"))
    assert any("gmsh" in k for k in s["skipped"])
    assert any("output files h5, xdmf" in k for k in s["skipped"])
    assert "static" in s["loading"] and s["load_steps"] == 1
