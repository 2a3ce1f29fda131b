"""The option registry (contact/options.py) is the one declaration: -help, the checker, the
loops' defaults and the README's table all come from it; presets leave nothing behind."""
import os

import pytest
from conftest import ROOT, paper_scene, solve
from petsc4py import PETSc

from contact import options
from contact.solvers.paper.apg import APG
from contact.solvers.paper.fixedpoint import FixedPoint
from contact.solvers.paper.ssn import SemismoothNewton
from contact.solvers.paper.uzawa import Uzawa


def test_readme_table_is_the_registry():
    with open(os.path.join(ROOT, "README.md")) as f:
        readme = f.read()
    assert options.markdown_table() in readme


def test_checker_knows_every_registered_name_and_rejects_a_typo():
    known = options.known()
    assert {o.name for o in options.REGISTRY} <= known
    assert "statics_check" in known                # read, so declared (it was not)
    opts = PETSc.Options()
    opts.setValue("statics_check", "0")
    options.check(opts)                            # no error
    opts.setValue("statics_chek", "0")
    with pytest.raises(options.OptionsError, match="did you mean -statics_check"):
        options.check(opts)


def test_loop_defaults_come_from_the_registry_then_the_scene_then_the_options(comm):
    for loop, prefix in ((APG, "apg_"), (SemismoothNewton, "ssn_"), (Uzawa, "uzawa_"),
                         (FixedPoint, "fp_")):
        assert set(loop.option_names()) == {o.name[len(prefix):] for o in options.REGISTRY
                                            if o.name.startswith(prefix)}
    apg = APG(comm)
    assert apg.rtol == options.BY_NAME["apg_rtol"].default == 1e-8
    sc = paper_scene(nd=1, apg_rtol=1e-5)
    assert apg.set_from_options(sc).rtol == 1e-5
    PETSc.Options().setValue("apg_rtol", "1e-4")
    assert apg.set_from_options(sc).rtol == 1e-4


def test_a_preset_is_removed_after_its_solve(comm):
    """-solver_mode fast inserts its options for the solve only; the user's own win."""
    opts = PETSc.Options()
    opts.setValue("solver_mode", "fast")
    opts.setValue("ssn_pc_lag", "2")
    before = dict(opts.getAll())
    pr = solve(paper_scene(nd=1, uzawa_r=1e6), comm)
    assert pr.inner.name == "ssn" and pr.inner.pc_lag == 2 and pr.fp.warm_start == "xl"
    assert dict(opts.getAll()) == before


def test_element_names_are_the_elements():
    from contact import fem
    assert options.ELEMENT_NAMES == tuple(fem.ELEMENTS)


def test_solver_modes_are_the_presets():
    """The values -solver_mode accepts are those the driver has a preset for."""
    from contact.solvers import driver
    assert set(options.SOLVER_MODE_NAMES) == set(driver.SOLVER_MODES)
    with pytest.raises(ValueError, match="-solver_mode must be one of newton, faithful, fast"):
        options.solver_mode({"solver": {"mode": "quick"}})
