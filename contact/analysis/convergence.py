"""Mesh convergence: a continuum value extrapolated from a sequence of meshes, with an
estimate of its own error, and what it costs to reach an accuracy.

In the asymptotic range a quantity computed on meshes of size h = 1/Nd behaves like
q(h) = q* + C h^p. Three meshes determine q*, C and p (generalised Richardson
extrapolation: p from the ratio of the two differences, by bisection, for any ratios of
h). `continuum` extrapolates from the finest triple of meshes that double (Nd, 2 Nd, 4 Nd;
the finest three where none double) and again from the next-finest such triple (or, where
there is none, the finest other three consecutive meshes: 8, 16, 32 and 16, 24, 32); the
difference of the two limits is the error estimate of the first (the usual
difference-of-successive-extrapolations estimate: it is small only where both triples
are in the asymptotic range and agree). Where the differences of the finest triple change
sign or do not shrink, there is no extrapolation: the finest value stands, with the last
difference as its error estimate, and the result says so.

`cost` reads off what an accuracy costs from a run sequence: the cheapest run from which
every finer run stays within the level (a coarse mesh whose error crosses zero by chance
does not count), or, past the finest run, a projection from the observed order and the
growth of the run time with the number of unknowns, marked as such.
"""
import math

#: range of orders p the bisection looks in
P_MIN, P_MAX = 0.05, 8.0


def richardson(h, q):
    """(q*, p, C) of q = q* + C h^p through three points, h1 > h2 > h3; None where the
    differences change sign or need an order outside [P_MIN, P_MAX] (with h halving: the
    differences do not shrink)."""
    (h1, h2, h3), (q1, q2, q3) = h, q
    if not h1 > h2 > h3 > 0:
        raise ValueError(f"richardson: mesh sizes must decrease, got {h}")
    d1, d2 = q1 - q2, q2 - q3
    if d1 == 0.0 or d1 * d2 <= 0.0:
        return None
    ratio = d1 / d2

    def f(p):                               # increasing in p: (h1^p - h2^p) / (h2^p - h3^p)
        return (h1 ** p - h2 ** p) / (h2 ** p - h3 ** p) - ratio

    lo, hi = P_MIN, P_MAX
    if f(lo) > 0.0 or f(hi) < 0.0:
        return None
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) < 0.0 else (lo, mid)
    p = 0.5 * (lo + hi)
    C = d2 / (h2 ** p - h3 ** p)
    return q3 - C * h3 ** p, p, C


def triples(nds):
    """The triples of sizes to extrapolate from, finest first: those that double
    (Nd, 2 Nd, 4 Nd), else consecutive triples."""
    s = sorted(set(nds))
    have = set(s)
    dbl = [(n, 2 * n, 4 * n) for n in s if 2 * n in have and 4 * n in have]
    if dbl:
        return sorted(dbl, key=lambda t: t[2], reverse=True)
    return [tuple(s[i - 2:i + 1]) for i in range(len(s) - 1, 1, -1)]


def continuum(nds, values):
    """The continuum value of a quantity from its values on meshes Nd (h = 1/Nd).

    Returns a dict: value, error (the estimate of |value - q*|), order (observed p of the
    triple used, None without extrapolation), triple, second (the next triple's
    extrapolation: value, order, triple; None if there is none), method (a sentence)."""
    q = dict(zip(nds, values))
    if len(q) < 2:
        raise ValueError("continuum: needs at least two meshes")
    found, ts = [], triples(q)
    s = sorted(q)
    ts += [t for t in (tuple(s[i - 2:i + 1]) for i in range(len(s) - 1, 1, -1))
           if t not in ts]                     # (the second estimate: any other triple)
    for t in ts:
        r = richardson([1.0 / n for n in t], [q[n] for n in t])
        if r is not None:
            found.append((t, r))
        if len(found) == 2:
            break
    fine, prev = q[s[-1]], q[s[-2]]
    first = ts[0] if len(s) >= 3 else None
    if not found or found[0][0] != first:
        return {"value": fine, "error": abs(fine - prev), "order": None, "triple": None,
                "second": None,
                "method": (f"no extrapolation (Nd = {', '.join(map(str, first))}: the "
                           "differences change sign or do not shrink)" if first else
                           "no extrapolation (two meshes)") +
                          f": the value at Nd = {s[-1]}, its error estimate the difference "
                          f"to Nd = {s[-2]}"}
    (t1, (v1, p1, _)), second = found[0], (found[1] if len(found) > 1 else None)
    out = {"value": v1, "order": p1, "triple": list(t1), "second": None}
    if second is not None:
        t2, (v2, p2, _) = second
        out.update(error=abs(v1 - v2), second={"value": v2, "order": p2, "triple": list(t2)},
                   method=f"Richardson from Nd = {', '.join(map(str, t1))} (order {p1:.2f}); "
                          f"error estimate: its difference to the extrapolation from Nd = "
                          f"{', '.join(map(str, t2))} (order {p2:.2f})")
    else:
        out.update(error=abs(v1 - q[t1[2]]),
                   method=f"Richardson from Nd = {', '.join(map(str, t1))} (order {p1:.2f}); "
                          f"error estimate: the extrapolation's own correction (no second "
                          f"triple)")
    return out


def cost(rows, level, order=None):
    """What relative error `level` costs. rows: (nd, dofs, time, error) of runs in any
    order. Returns {"nd", "time", "projected": False} for the cheapest run from which
    every finer run has error <= level; else, with an order p > 0, a projection from the
    finest run (Nd x (e / level)^(1/p); time grown as dofs^a, a fitted on the finest
    three runs): {"nd", "time", "projected": True}; else None."""
    rows = sorted(rows)
    if not rows:
        return None
    i = len(rows)
    while i > 0 and rows[i - 1][3] <= level:
        i -= 1
    if i < len(rows):
        nd, _, time, _ = rows[i]
        return {"nd": nd, "time": time, "projected": False}
    if not order or order <= 0 or len(rows) < 2:
        return None
    nd, dofs, time, err = rows[-1]
    if err <= 0:
        return None
    need = nd * (err / level) ** (1.0 / order)
    tail = rows[-3:]
    xs = [math.log(r[1]) for r in tail]
    ys = [math.log(r[2]) for r in tail]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    a = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx > 0 else 1.0
    a = max(a, 1.0)                  # at least linear in the unknowns
    return {"nd": need, "time": time * (need / nd) ** (3 * a), "projected": True}
