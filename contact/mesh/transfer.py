"""Coarse-to-fine transfer on the mesh hierarchy (hierarchy.py), for a nested-iteration start.

P, the Q1 interpolation from a level to its regular refinement (hierarchy.prolongation),
acts on each displacement component alike: a fine vertex gets the coarse field at its
place, which is the value of a coarse vertex, the mean of an edge's 2, a face's 4 or a
cell's 8. It reproduces every trilinear field exactly, on any hexahedral mesh the
hierarchy refines (box, rotated, or a foundation frame: the displacement is prolonged in
x, y, z and turned into each problem's own basis).

Contact space (multiplier l, slip bound g, ...): values live on the contact nodes, a subset
of the contact face's vertices (nodes with a clamped normal dof are left out). A contact
Vec rides through P on the normal component of a displacement-shaped carrier, beside the
indicator of the coarse contact nodes: the fine value is
    sum_k w_k v_k / sum_k w_k  over the coarse contact nodes k of the fine node's parent face
(plain bilinear interpolation where the 4 corners are contact nodes; a convex combination
over those present otherwise, e.g. next to a clamped edge; 0 where none is). A fine node on
the contact face lies on a face of its parent cell, so only that face's nodes weigh.
All of it is Mat and Vec operations, collective, with no array of global size.
"""
import numpy as np


def prolong_displacement(P, coarse, fine, xc, xf):
    """xf <- the fine x of P u_c: the coarse problem's displacement u_c = xc + u_D at the
    fine nodes (through x, y, z when either problem has a contact frame), less the fine
    prescribed displacement u_D, 0 at fine.clamped. Prolonging x itself would lose the
    lifting in the coarse cells next to a prescribed displacement (x is 0 at its nodes,
    u_D only at the fine level's). Collective; returns xf."""
    u = coarse.disc.displacement(xc)                 # xc itself without a frame or u_D
    P.mult(u, xf)
    if u is not xc:
        u.destroy()
    fine.disc.to_frame(xf)
    if fine.disc.u_D is not None:
        xf.axpy(-1.0, fine.disc.u_D)
    if fine.disc.pair is not None:                   # a contact pair's basis (pairs.py)
        fine.disc.pair.from_displacement(xf)
    xf.setValues(fine.clamped, np.zeros(len(fine.clamped)))
    xf.assemble()
    return xf


def prolong_field(P, coarse, fine, vc):
    """A new fine Vec: P v_c, a displacement-shaped field of the coarse problem's basis
    (no lifting: a dual solution, analysis/goal.py) in the fine problem's basis, through
    x, y, z where either has a contact frame. Collective."""
    u = coarse.disc.to_xyz(vc)
    vf = fine.x.duplicate()
    P.mult(u, vf)
    if u is not vc:
        u.destroy()
    fine.disc.to_frame(vf)
    return vf


def prolong_contact(P, coarse, fine, vc, vf):
    """vf <- the coarse contact-space Vec vc interpolated at the fine contact nodes (see the
    module docstring). Collective; returns vf."""
    if coarse.cs is None or fine.cs is None:
        raise ValueError("both problems need a contact part")
    cc, cf = coarse.cs, fine.cs
    yc, mc = coarse.x.duplicate(), coarse.x.duplicate()
    yf, mf = fine.x.duplicate(), fine.x.duplicate()
    one, den = cc.vec(1.0), cf.vec()
    for y, v in ((yc, vc), (mc, one)):
        y.set(0.0)
        cc.scatter(v, y, 2)
    P.mult(yc, yf)
    P.mult(mc, mf)
    cf.gather(yf, vf, 2)
    cf.gather(mf, den, 2)
    den.shift(1e-300)                                # no coarse contact node: 0 / 1e-300
    vf.pointwiseDivide(vf, den)
    for v in (yc, mc, yf, mf, one, den):
        v.destroy()
    return vf
