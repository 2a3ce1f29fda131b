"""The same scene on 1 and 2 ranks gives the same answer (run under mpirun -n 2)."""
from conftest import gather, only_in_parallel, paper_scene, rel_err, solve
from petsc4py import PETSc


@only_in_parallel
def test_two_ranks_equal_one_rank():
    sc = paper_scene(nd=3, uzawa_r=1e6, apg_rtol=1e-12, uzawa_rtol=1e-9, fp_rtol=1e-9)
    par = solve(sc, PETSc.COMM_WORLD)
    ser = solve(sc, PETSc.COMM_SELF)
    assert par.partitioner != "none"
    xyz_p, u_p = gather(par)[:2]
    xyz_s, u_s = gather(ser)[:2]
    assert (xyz_p == xyz_s).all()
    assert rel_err(u_p, u_s) < 1e-8
    assert par.fp.iterations == ser.fp.iterations
    assert par.iterations()["apg_first"] == ser.iterations()["apg_first"]


@only_in_parallel
def test_every_rank_owns_part_of_the_mesh():
    pr = solve(paper_scene(nd=2, uzawa_r=1e6), PETSc.COMM_WORLD)
    assert pr.conn.shape[0] > 0 and pr.x.getLocalSize() > 0
