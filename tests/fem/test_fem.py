"""Q1 elasticity against closed forms: exact uniform-strain energy, rigid modes, weights,
and a linear-elasticity box solve against the uniaxial-stress solution."""
import numpy as np
import pytest
from conftest import block_scene, gather, rel_err, solve

from contact import fem
from contact.mesh import HEX_REF, MeshError


def _distorted_hex(seed=0):
    rng = np.random.default_rng(seed)
    X = 0.5 * (HEX_REF + 1.0) * np.array([2.0, 1.0, 1.5])
    return X + 0.1 * rng.standard_normal(X.shape)


def _stiffness_tensor(lam, mu):
    I = np.eye(3)
    return (lam * np.einsum("ij,kl->ijkl", I, I)
            + mu * (np.einsum("ik,jl->ijkl", I, I) + np.einsum("il,jk->ijkl", I, I)))


def test_uniform_strain_energy_is_exact_on_a_distorted_hex():
    """u = eps x is in Q1, so u^T K u = eps : C : eps * volume exactly."""
    X = _distorted_hex()
    lam, mu = fem.lame(210.0, 0.3)
    K = fem.element_stiffness(X[None], lam, mu)[0]
    eps = np.array([[1.0, 0.2, -0.1], [0.2, -0.5, 0.3], [-0.1, 0.3, 0.7]])
    u = (X @ eps.T).ravel()
    vol = fem.element_volume_weights(X[None]).sum()
    exact = np.einsum("ij,ijkl,kl->", eps, _stiffness_tensor(lam, mu), eps) * vol
    assert u @ K @ u == pytest.approx(exact, rel=1e-12)


def test_element_matrix_symmetric_with_six_rigid_modes():
    K = fem.element_stiffness(_distorted_hex(1)[None], *fem.lame(1.0, 0.25))[0]
    assert np.abs(K - K.T).max() < 1e-13 * np.abs(K).max()
    ev = np.linalg.eigvalsh(K)
    assert np.sum(np.abs(ev) < 1e-10 * ev.max()) == 6
    assert ev.min() > -1e-10 * ev.max()


def test_volume_and_face_weights():
    X = 0.5 * (HEX_REF + 1.0) * np.array([2.0, 3.0, 0.5])
    assert fem.element_volume_weights(X[None]).sum() == pytest.approx(3.0)
    quad = np.array([[[0, 0, 0], [2, 0, 0], [2, 3, 0], [0, 3, 0]]], dtype=float)
    assert np.allclose(fem.face_weights(quad), 1.5)       # trapezoidal: area / 4


def test_inverted_cell_is_rejected():
    X = 0.5 * (HEX_REF + 1.0)
    X[:, 2] *= -1.0                                        # mirror: negative Jacobian
    with pytest.raises(MeshError, match="inverted"):
        fem.element_stiffness(X[None], 1.0, 1.0)


UNIAXIAL = {
    "sym_x": {"plane": ["x", 0.0], "type": "dirichlet", "components": ["x"]},
    "sym_y": {"plane": ["y", 0.0], "type": "dirichlet", "components": ["y"]},
    "sym_z": {"plane": ["z", 0.0], "type": "dirichlet", "components": ["z"]},
    "end": {"plane": ["x", 2.0], "type": "traction", "traction": [5.0, 0.0, 0.0]},
}


def test_uniaxial_stress_closed_form(comm):
    """Rollers on three faces, traction p on x = L: u = p/E (x, -nu y, -nu z), exact in Q1."""
    E, nu, p = 1.0e3, 0.3, 5.0
    pr = solve(block_scene(UNIAXIAL, nd=3, young=E, poisson=nu, size=(2.0, 1.0, 1.0)), comm)
    assert pr.mode == "linear" and pr.apg is None        # no contact: one KSP solve
    xyz, u = gather(pr)[:2]
    exact = p / E * np.c_[xyz[:, 0], -nu * xyz[:, 1], -nu * xyz[:, 2]]
    assert rel_err(u, exact) < 1e-8


@pytest.mark.parametrize("element", ["q1", "bbar"])
def test_element_stiffness_shared_shapes_equal_per_cell(element):
    """Cells of one shape share one K_e (fem.element_stiffness): equal to the per-cell
    computation, on a mix of translated copies of one cell and distorted cells."""
    from contact import fem
    rng = np.random.default_rng(3)
    ref = np.array([[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0],
                    [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=float) * [0.3, 0.2, 0.1]
    copies = ref[None] + 10.0 * rng.random((40, 1, 3))           # translated: one shape
    odd = ref[None] + 0.01 * rng.standard_normal((5, 8, 3))       # five other shapes
    X = np.concatenate([copies, odd])[rng.permutation(45)]
    K = fem.element_stiffness(X, 2.0, 1.0, element)
    each = np.stack([fem.element._element_stiffness(X[i:i + 1], 2.0, 1.0, element)[0]
                     for i in range(45)])
    assert np.abs(K - each).max() < 1e-12 * np.abs(each).max()
