"""Crosspoints (fem/pairs_crosspoints.py): a block on a base and against a wall, the block
the slave side of both pairs, the nodes of its edge where bottom and side meet on both
pairs' slave faces; the first pair keeps them, the second's dual basis takes them in at
their neighbours. The patch test (uniform pressures on both faces, the edge included), the
pairs' forces, and the refusals that remain."""
import numpy as np
import pytest
from conftest import solve

from contact import scene as scenes
from contact.analysis import stress
from contact.scene import SceneError

P, Q = 0.01, 0.02            # the wall's push along x, the load on the block's top


def corner(friction=0.0, young=(1.0, 1.0, 1.0), cells=((4, 4, 2), (5, 5, 3), (2, 3, 4))):
    """A base [0,1]^2 x [0,1], a block [0,1]^2 x [1,2] on it and a wall [1,2] x [0,1] x
    [1,2] beside it (the three meshes non-matching at both interfaces), symmetry planes
    x = 0 (base, block) and y = 0; the base's bottom and the wall's top held along z, the
    block's top pressed by Q, the wall's back by P. Exact: uniform stresses, the block's
    diag(-P, 0, -Q), the base's -Q along z, the wall's -P along x."""
    mat = [{"young": e, "poisson": 0.3} for e in young]
    box = lambda lo, hi, n, m: {"lower": lo, "upper": hi, "cells": list(n),  # noqa: E731
                                "material": m}
    return {"name": "corner",
            "bodies": {"base": box([0, 0, 0], [1, 1, 1], cells[0], mat[0]),
                       "block": box([0, 0, 1], [1, 1, 2], cells[1], mat[1]),
                       "wall": box([1, 0, 1], [2, 1, 2], cells[2], mat[2])},
            "boundary": {
                "bottom": {"type": "dirichlet", "body": "base", "plane": ["z", 0.0],
                           "components": ["z"]},
                "wall_top": {"type": "dirichlet", "body": "wall", "plane": ["z", 2.0],
                             "components": ["z"]},
                "press": {"type": "traction", "body": "block", "plane": ["z", 2.0],
                          "traction": [0.0, 0.0, -Q]},
                "push": {"type": "traction", "body": "wall", "plane": ["x", 2.0],
                         "traction": [-P, 0.0, 0.0]},
                "on_base": {"type": "contact", "body": "block", "plane": ["z", 1.0],
                            "master": {"body": "base"}},
                "on_wall": {"type": "contact", "body": "block", "plane": ["x", 1.0],
                            "master": {"body": "wall"}},
                "sym_x": {"type": "symmetry", "plane": ["x", 0.0]},
                "sym_y": {"type": "symmetry", "plane": ["y", 0.0]}},
            "contact": {"friction": friction},
            "solver": {"mode": "newton", "newton_rtol": 1e-12}}


@pytest.mark.parametrize("young", [(1.0, 1.0, 1.0), (3.0, 1.0, 2.0)])
def test_patch_crosspoint(comm, young):
    """Uniform stresses in the three bodies to 1e-8, the multiplier Q at every slave node
    of the bottom (the crosspoint edge too) and P at every one of the side, each pair's
    force its pressure times its face's area (1)."""
    pr = solve(scenes.validate(corner(young=young)), comm)
    assert pr.converged
    sig = stress.body_stress(pr)["cell"]
    mpi = pr.comm.tompi4py()
    want = {"base": [0, 0, -Q], "block": [-P, 0, -Q], "wall": [-P, 0, 0]}
    body = pr.disc.body_of if hasattr(pr, "disc") else None
    lam = pr.cs.local_array(pr.l)
    X = pr.cs.coordinates
    side = np.abs(X[:, 0] - 1.0) < 1e-12
    bottom = np.abs(X[:, 2] - 1.0) < 1e-12
    assert mpi.allreduce(int(lam.size)) == 6 * 6 + 6 * 3          # the edge's 6: bottom's
    assert np.all(np.abs(lam[bottom] - Q) < 1e-8 * Q)
    assert np.all(np.abs(lam[side & ~bottom] - P) < 1e-8 * P)
    from contact.io import report
    s = report.summary(pr, 0.0)["contact_pairs"]
    assert abs(s["on_base"]["contact_result"]["normal"] - Q) < 1e-8 * Q
    assert abs(s["on_wall"]["contact_result"]["normal"] - P) < 1e-8 * P
    cells = np.asarray(sig)
    assert cells.shape[1] == 6
    smax = np.abs(cells[:, [1, 3, 4, 5]]).max(initial=0.0)
    assert smax < 1e-8 * Q
    del body, want
