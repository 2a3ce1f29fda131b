"""Small vector geometry shared by the scene, the mesh and the contact frame: unit vectors,
the coordinate axis of a normal, an orthonormal basis with a given normal, rotations."""
import math

import numpy as np


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def axis_of(normal, tol=1e-12):
    """k when the unit `normal` is +e_k, else None."""
    n = unit(normal)
    k = int(np.argmax(np.abs(n)))
    return k if n[k] > 0 and np.all(np.abs(np.delete(n, k)) <= tol) else None


def basis(normal):
    """Q (3, 3) with rows t1, t2, n: t1 the coordinate axis most nearly orthogonal to n,
    projected on the plane (exactly e_c when n_c = 0), t2 = n x t1. Normals (m, 3): Q (m,
    3, 3), one a row."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    c = np.argmin(np.abs(n), axis=-1)
    e = np.eye(3)[c]
    nc = np.take_along_axis(n, c[..., None], axis=-1)
    t1 = e - nc * n
    t1 /= np.linalg.norm(t1, axis=-1, keepdims=True)
    t1 = np.where(nc == 0.0, e, t1)
    return np.stack([t1, np.cross(n, t1), n], axis=-2)


def rotation(axis, degrees):
    """The rotation matrix R (3, 3) of `degrees` about `axis` (right hand; Rodrigues)."""
    k = unit(axis)
    th = math.radians(degrees)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(th) * K + (1.0 - math.cos(th)) * (K @ K)


def turn_scene(sc, axis, degrees, R):
    """scene.turned's changes to the scene dict sc (in place): mesh.rotate, and its
    tractions, body force and foundation turned by R."""
    sc["mesh"]["rotate"] = {"axis": [float(a) for a in axis], "degrees": float(degrees)}
    turn = lambda v: [float(c) for c in R @ np.asarray(v, dtype=float)]   # noqa: E731
    for part in sc["boundary"].values():
        if "traction" in part:
            part["traction"] = turn(part["traction"])
    sc["body_force"] = turn(sc.get("body_force", [0.0, 0.0, 0.0]))
    fd = sc.setdefault("contact", {}).get("foundation", {})
    sc["contact"]["foundation"] = {"point": turn(fd.get("point", [0.0, 0.0, 0.0])),
                                   "normal": turn(fd.get("normal", [0.0, 0.0, 1.0]))}
