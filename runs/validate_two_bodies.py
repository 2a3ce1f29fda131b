"""Two-body Hertz (runs/scenes/hertz_two_bodies.yaml) against the closed form.

Two identical elastic bodies (E, nu) touching along a sphere of radius R (the ball's lower
face, the block's flat top): Hertz with E* = E / (2 (1 - nu^2)), i.e. the one-body formulas
(contact/validation/theory.py) with E / 2. As runs/validate.py does for one body, the
contact radius and peak pressure (fits of p^2 = p0^2 (1 - r^2 / a^2) to the slave nodes'
multipliers, contact/validation/hertz.py: analyse) are compared with Hertz's at the computed
force P (4 x the quarter's), which the finite bodies' bulk compliance does not enter; the
force against Hertz's P(delta) with delta = d (the top's displacement) less nothing but the
Boussinesq correction of each body (approach_correction at its height), first order in
a / H only.

    python runs/validate_two_bodies.py [--gmsh] [nd ...]       (default 2 4)

--gmsh: runs/scenes/hertz_two_bodies_gmsh.yaml, the ball read by gmsh (meshes/ball.geo;
nd is then the coarse level's, here the only one: the box scene's mesh at the same nd).
"""
import os
import sys
import time

import petsc4py

petsc4py.init(sys.argv[:1])

from petsc4py import PETSc  # noqa: E402

from contact import scene as scenes  # noqa: E402
from contact.problem import ContactProblem  # noqa: E402
from contact.validation import theory as th  # noqa: E402
from contact.validation.hertz import R_SPHERE, analyse, approach_correction  # noqa: E402

SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "scenes",
                     "hertz_two_bodies.yaml")
GMSH_SCENE = SCENE.replace(".yaml", "_gmsh.yaml")


def two_bodies_scene(nd, gmsh=False):
    sc = scenes.load(GMSH_SCENE if gmsh else SCENE)
    sc.setdefault("mesh", {})["nd"] = nd
    return scenes.validate(sc)


def study(nd, gmsh=False):
    """The solved scene at nd: Hertz's a, p0 at the computed P, and P against P(delta)."""
    sc = two_bodies_scene(nd, gmsh)
    ball = sc["bodies"]["ball"]
    E, nu = (ball["material"][k] for k in ("young", "poisson"))
    d = -sc["boundary"]["push"]["displacement"][2]
    H = ball["mesh"]["parameters"]["H"] if gmsh else ball["upper"][2] - ball["lower"][2]
    t0 = time.perf_counter()
    pr = ContactProblem(sc, PETSc.COMM_WORLD).solve()
    t = time.perf_counter() - t0
    a = analyse(pr, nu, E=E / 2.0)
    delta = d + 2.0 * approach_correction(a["P"], nu, E=E, H=H)
    a.update(nd=nd, dofs=pr.n_dofs, time=t, delta=delta,
             P_hertz=th.hertz_force(delta, R_SPHERE, E / 2.0, nu),
             a_delta=th.hertz_radius_from_indentation(delta, R_SPHERE))
    return a


def main(nds, gmsh=False):
    for nd in nds:
        a = study(nd, gmsh)
        PETSc.Sys.Print(
            f"nd={nd} dofs={a['dofs']} nodes={a['nodes_in_contact']} P={a['P']:.5e} "
            f"a_fit={a['a_fit']:.4f} a_area={a['a_area']:.4f} a_H(P)={a['a_hertz']:.4f} "
            f"({a['a_fit'] / a['a_hertz'] - 1:+.3f}) p0_fit={a['p0_fit']:.5f} "
            f"p0_H(P)={a['p0_hertz']:.5f} ({a['p0_fit'] / a['p0_hertz'] - 1:+.3f}) "
            f"delta={a['delta']:.5f} P_H(delta)={a['P_hertz']:.5e} "
            f"({a['P'] / a['P_hertz'] - 1:+.3f}) a_H(delta)={a['a_delta']:.4f} "
            f"t={a['time']:.1f}s")


if __name__ == "__main__":
    args = sys.argv[1:]
    main([int(n) for n in args if n != "--gmsh"] or [2, 4], "--gmsh" in args)
