"""Crosspoints of several contact pairs (fem/pairs.py): a node on the slave faces of two pairs
(a block on a base and against a wall: the edge where its bottom meets its side).

The pair listed first keeps the node as its slave node (all three components relative to
its master, as any other). The later pair drops it from its multiplier space and modifies
its dual basis at the crosspoint, as Wohlmuth (2000; Acta Numerica 2011) and
Popp, Gee & Wall (2010) do at a slave surface's boundary: the crosspoint j's dual function
joins those of its neighbours k on the slave faces, psi_k' = psi_k + a_kj psi_j (a_kj >= 0,
sum_k a_kj = 1: the multipliers still hold constants, so a uniform pressure is exact). The
constraint of k, int psi_k' (u_s - u_m) = D_k g_k + sum_j a_kj D_j g_j, reads with
c_kj = a_kj D_j / D_k as D_k times
    u~_k = g_k + sum_j c_kj g_j = u_k + sum_j c_kj u_j - Q_k u_m,  Q_k = P_k + sum_j c_kj P_j,
its weight D_k unchanged; the multipliers' reaction on j is sum_k c_kj D_k lambda_k. The
change of basis stays u = Z u~ with Z's row k = d_k u~_k + Q_k u_m - c_kj u_j, u_j being Z's
row j (its first pair's: d_j u~_j + P_j u_m'); Z^-1's row k is d_k (u_k + c_kj u_j - Q_k
u_m). The contact set's weight at j is its first pair's D_j alone (`weight_off`).

a_kj: the share of j's lumped weight on each slave face of the later pair at j (the
triangle at j's corner) goes to the face's corners beside j that are no crosspoints (the
opposite corner where both are). The q2 element's 9-node faces (fem/mortar_q2.py): the
face's share (its area's) goes to the nodes next to j on the face's 3 x 3 grid that are no
crosspoints (a corner's or an edge node's inner neighbour), else one diagonal step away.
The rigid foundation's contact nodes beside the pairs come first of all (`taken`: a block
on the foundation against a wall). A pair's force
(analysis/stress.py: by_pair) weighs lambda_k by int psi_k' = D_k + sum_j a_kj D_j.
Refused (PairError, one line): a node on three contact parts' slave faces, a face of the
later pair whose corners (q2: nodes) are all crosspoints (two parts on one slave face), a
neighbour k the master does not cover.
"""
import numpy as np


class PairError(ValueError):
    """A scene's contact pairs that this change of basis cannot hold (one line, the same on
    every rank: the surfaces are every rank's); the discretisation raises it as SceneError."""


def _shares(part, isx, first):
    """(k, j, a_kj) (indices into the part's slave face nodes) for the crosspoints isx
    (first: the earlier contact part that keeps them, as the refusal names it)."""
    fs, xs = part["faces"], part["xs"]
    f, i = np.nonzero(isx[fs])
    j = fs[f, i]
    side = np.stack([fs[f, (i + 1) % 4], fs[f, (i + 3) % 4]], axis=1)
    ok = ~isx[side]
    opp = fs[f, (i + 2) % 4]
    none = ~ok.any(axis=1)
    if np.any(none & isx[opp]):
        raise PairError(f"{first} and contact pair {part['name']!r} share slave nodes on a "
                        f"whole face: contact parts may share only the nodes where their "
                        f"slave faces meet (crosspoints)")
    side[none, 0], ok[none, 0] = opp[none], True
    e1, e2 = xs[fs[f, (i + 1) % 4]] - xs[j], xs[fs[f, (i + 3) % 4]] - xs[j]
    tri = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
    tri = tri / np.bincount(j, tri, minlength=xs.shape[0])[j]
    a = tri[:, None] * ok / ok.sum(axis=1, keepdims=True)
    kk, jj, aa = side[ok], np.repeat(j, 2)[ok.ravel()], a[ok]
    return kk, jj, aa


#: the 9-node face's nodes on a 3 x 3 grid (fem/mortar_q2.py's order: corners, edges, centre)
GRID9 = np.array([[0, 0], [2, 0], [2, 2], [0, 2], [1, 0], [2, 1], [1, 2], [0, 1], [1, 1]])
#: NEAR9[i]: the nodes next to node i on the grid (one step), then those one diagonal away
_d = np.abs(GRID9[:, None, :] - GRID9[None, :, :]).sum(axis=2)
_c = np.abs(GRID9[:, None, :] - GRID9[None, :, :]).max(axis=2)
NEAR9 = ((_d == 1), (_d == 2) & (_c == 1))


def _shares9(part, isx, first):
    """_shares for the q2 element's 9-node faces: a crosspoint j's weight on each face
    (its share of j's lumped weight, the face's area times j's Simpson weight there, the
    same weight on every face of j: corner or edge node) goes to the face's nodes next to
    j on its 3 x 3 grid that are no crosspoints, else to those one diagonal step away."""
    fs, xs = part["faces"], part["xs"]
    f, i = np.nonzero(isx[fs])
    j = fs[f, i]
    ok = [~isx[fs[f]] & near[i] for near in NEAR9]
    use = np.where(ok[0].any(axis=1, keepdims=True), ok[0], ok[1])
    if not use.any(axis=1).all():
        raise PairError(f"{first} and contact pair {part['name']!r} share slave nodes on a "
                        f"whole face: contact parts may share only the nodes where their "
                        f"slave faces meet (crosspoints)")
    c = xs[fs[f, :4]]
    area = 0.5 * np.linalg.norm(np.cross(c[:, 2] - c[:, 0], c[:, 3] - c[:, 1]), axis=1)
    w = area / np.bincount(j, area, minlength=xs.shape[0])[j]
    a = w[:, None] * use / use.sum(axis=1, keepdims=True)
    jj = np.repeat(j, 9).reshape(-1, 9)
    return fs[f][use], jj[use], a[use]


def take(parts, taken=None):
    """Drops each crosspoint from the later pairs' parts (fem/pairs.py's _surface dicts,
    changed in place: sid, ok, gaps, E's entries, rows) and returns per such pair the moved
    couplings: (part index, k, j, c_kj (global vertex numbers), the dropped entries of the
    j rows (srow, mcol, v))."""
    moved = []
    seen = np.zeros(0, dtype=np.int64) if taken is None else taken[1]
    orig = [p["sid"] for p in parts]
    names = [f"contact pair {p['name']!r}" for p in parts]
    if taken is not None:                       # the foundation's nodes: first of all
        orig, names = [taken[1]] + orig, [taken[0]] + names
    before = len(orig) - len(parts)
    for n, b in enumerate(parts):
        isx = np.isin(b["sid"], seen)
        seen = np.union1d(seen, b["sid"])
        if not isx.any():
            continue
        if any(np.isin(b["sid"][isx], np.intersect1d(p, q)).any()
               for i, p in enumerate(orig[:n + before]) for q in orig[i + 1:n + before]):
            raise PairError(f"contact pair {b['name']!r}: a node lies on three contact "
                            f"parts' slave faces")
        first = next(m for m, o in zip(names[:n + before], orig)
                     if np.isin(o, b["sid"]).any())
        k, j, a = (_shares if b["faces"].shape[1] == 4 else _shares9)(b, isx, first)
        use = b["ok"][j]                        # an uncovered j has no multiplier to move
        k, j, a = k[use], j[use], a[use]
        if not b["ok"][k].all():
            raise PairError(f"contact pair {b['name']!r}: a slave node beside a crosspoint "
                            f"is not covered by the master")
        c = a * b["D"][j] / b["D"][k]
        sid = b["sid"]
        drop = np.isin(b["srow"], sid[isx])
        b["xid"], b["Dx"] = sid[isx], b["D"][isx]                  # (weight_off)
        ek, inv = np.unique(sid[k], return_inverse=True)     # psi_k' integrates to D_k + this
        b["extra"] = (ek, np.bincount(inv.ravel(), a * b["D"][j], minlength=ek.size))
        moved.append((n, sid[k], sid[j], c, b["srow"][drop], b["mcol"][drop], b["v"][drop]))
        gaps = b["gaps"].copy()
        np.add.at(gaps, k, c * b["gaps"][j])
        keep = ~isx
        b.update(sid=sid[keep], ok=b["ok"][keep], D=b["D"][keep], gaps=gaps[keep],
                 srow=b["srow"][~drop], mcol=b["mcol"][~drop], v=b["v"][~drop],
                 rows=sid[keep][b["ok"][keep]])
    return moved


def _merged(rows, cols, w, keep, n_nodes):
    """Entries summed per (row, column): w (n, 3) times keep, kept where any was kept;
    sorted by row."""
    key, inv = np.unique(rows * n_nodes + cols, return_inverse=True)
    W = np.zeros((key.size, 3))
    K = np.zeros((key.size, 3), dtype=bool)
    np.add.at(W, inv.ravel(), w * keep)
    np.logical_or.at(K, inv.ravel(), keep)
    return key // n_nodes, key % n_nodes, W, K


def _ranges(rows, ids):
    """(t, s): for each ids[t], the positions s of its entries in the sorted rows."""
    lo, hi = np.searchsorted(rows, ids, "left"), np.searchsorted(rows, ids, "right")
    cnt = hi - lo
    t = np.repeat(np.arange(ids.size), cnt)
    s = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt) + np.repeat(lo, cnt)
    return t, s


def extend(E, moved, d_of, held, n_nodes):
    """(E, G): Z = D + E and Z^-1 = D (I + G) as entries (rows, cols, w (n, 3), keep (n, 3),
    sorted by row) with the crosspoints' couplings `moved` (take) in the rows k (module
    docstring). E: the other entries, sorted by row (G = -E there); d_of(ids): D's diagonal
    (n, 3) at the nodes ids; held: the clamped dofs of the pairs' nodes (all ranks')."""
    sr, mc, w, kp = E
    w = np.repeat(w[:, None], 3, axis=1)                         # per component
    hold = lambda ids: np.isin(3 * ids[:, None] + np.arange(3), held)    # noqa: E731
    ks = np.unique(np.concatenate([m[1] for m in moved]))
    mine = np.isin(sr, ks)
    e = [(sr[mine], mc[mine], w[mine], kp[mine])]
    g = [(sr[mine], mc[mine], -w[mine], kp[mine])]
    for _, k, j, c, jr, jc, jv in moved:
        both = ~hold(k) & ~hold(j)
        e.append((k, j, -c[:, None] * d_of(j), both))                  # -c u_j ...
        g.append((k, j, np.repeat(c[:, None], 3, axis=1), both))
        o = np.argsort(jr, kind="stable")                      # ... its later-pair P_j
        t, s = _ranges(jr[o], j)
        v = np.repeat((c[t] * jv[o][s])[:, None], 3, axis=1)
        kq = ~hold(k[t]) & ~hold(jc[o][s])
        e.append((k[t], jc[o][s], v, kq))
        g.append((k[t], jc[o][s], -v, kq))
        t, s = _ranges(sr, j)                                  # u_j = d_j u~_j + E_j u_m'
        e.append((k[t], mc[s], -c[t, None] * w[s], kp[s] & ~hold(k[t])))
    rest = (sr[~mine], mc[~mine], w[~mine], kp[~mine])
    out = []
    for parts, sign in ((e, 1.0), (g, -1.0)):
        X = _merged(*(np.concatenate([p[i] for p in parts]) for i in range(4)), n_nodes)
        R = (rest[0], rest[1], sign * rest[2], rest[3])
        cat = [np.concatenate([a, b]) for a, b in zip(R, X)]
        o = np.argsort(cat[0], kind="stable")
        out.append(tuple(a[o] for a in cat))
    return tuple(out)


def weight_off(moved, parts, nv_owned, rstart_block):
    """Per owned vertex, the later pairs' lumped weight D_j at their crosspoints (0
    elsewhere): the contact set sums every contact face's, j's is its first pair's."""
    out = np.zeros(nv_owned)
    for n, _, j, _, _, _, _ in moved:
        b = parts[n]
        jj = np.unique(j)
        loc = jj - rstart_block
        m = (loc >= 0) & (loc < nv_owned)
        out[loc[m]] += b["Dx"][np.searchsorted(b["xid"], jj[m])]
    return out


def check_nodes(parts):
    """PairError unless E E = 0 and no row of E is two pairs' (fem/pairs.py): no node
    is a slave node of two pairs (its face nodes), no slave node (a row of E) of one pair
    a master node (a column of E) of another."""
    for i, a in enumerate(parts):
        for b in parts[i + 1:]:
            if np.intersect1d(a["sid"], b["sid"]).size:
                raise PairError(f"contact pairs {a['name']!r} and {b['name']!r} share slave "
                                f"nodes: a node may be the slave node of one pair only")
        for b in parts:
            if b is not a and np.intersect1d(a["rows"], b["cols"]).size:
                raise PairError(f"contact pairs {a['name']!r} and {b['name']!r}: a slave node "
                                f"of {a['name']!r} is a master node of {b['name']!r} (a slave "
                                f"face may not be another pair's master face)")
