"""Figures of a run (-output_formats ...,png): PNG files beside solution.h5, drawn with
matplotlib (Agg) on rank 0 from output.figure_data (the contact face and the body's
surface, gathered for them; nothing of the volume).

  contact_status.png        stick / slip / separated map of the contact face (each node's
                            quarter of its faces, i.e. its weight w_j) and the friction use
                            |sigma_tau| / (F g)
  contact_pressure.png      normal pressure g and friction force |sigma_tau| (arrows: its
                            direction)
  contact_displacement.png  |u_tau| and -u_nu = u . n on the contact face
  body_von_mises.png        the deformed body (displacement magnified, the factor in the
                            title) coloured by the von Mises stress of its cells
  body_error_indicator.png  the same body coloured by the error indicator of its cells
                            (contact/analysis/estimate.py), where the run has a coarse level
  load_path.png             quasi-static runs: normal and tangential resultants and the
                            stick / slip areas against the load parameter t
With several bodies and several contact parts the three contact figures are drawn for each
part apart, named contact_status_<part>.png etc. (each pair's slave face, each face on the
foundation, seen along +e_k of its plane).
The contact face is drawn in the foundation's plane (coordinates along t1, t2 of
geometry.basis: x and y for the paper's foundation); faces touching a clamped node (not a
contact node) are hatched. A contact zone much smaller than the face is zoomed into.
Units are the scene's: lengths those of the mesh, stresses those of E.
"""
import os

import numpy as np

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.tri import Triangulation  # noqa: E402

from contact.geometry import basis  # noqa: E402

STATUS_COLORS = ("#c8c8c8", "#2c7bb6", "#d7191c")       # separated, stick, slip
STATUS_NAMES = ("separated", "stick", "slip")
DPI = 110
UNITS = "units of the scene: lengths as the mesh, stresses as E"


def _match(rows, table):
    """Index in `table` (m, 3) of each row of `rows` (k, 3) (exact coordinates), -1 if
    absent."""
    if table.shape[0] == 0:
        return np.full(rows.shape[0], -1)
    void = np.dtype((np.void, 3 * 8))
    t = np.ascontiguousarray(table, dtype=float).view(void).ravel()
    r = np.ascontiguousarray(rows, dtype=float).view(void).ravel()
    order = np.argsort(t)
    pos = np.clip(np.searchsorted(t[order], r), 0, t.size - 1)
    found = t[order][pos] == r
    return np.where(found, order[pos], -1)


def _axis_name(t):
    k = int(np.argmax(np.abs(t)))
    if abs(abs(t[k]) - 1.0) < 1e-12:
        return ("-" if t[k] < 0 else "") + "xyz"[k]
    return "along (" + ", ".join(f"{c:.2f}" for c in t) + ")"


class Face:
    """The contact face in the foundation's plane: projected nodes, triangles of the faces
    whose corners are all contact nodes, the sub-quadrilaterals of each node's share."""

    def __init__(self, data):
        c = data["contact"]
        Q = basis(data["normal"])
        self.labels = [_axis_name(Q[0]), _axis_name(Q[1])]
        p = data["point"]
        self.P = (c["coordinates"] - p) @ Q[:2].T                      # (m, 2)
        corners = data["contact_faces"]                                  # (f, 4, 3)
        idx = _match(corners.reshape(-1, 3), c["coordinates"]).reshape(-1, 4)
        self.C = (corners - p) @ Q[:2].T                                 # (f, 4, 2)
        self.idx = idx
        self.full = full = np.all(idx >= 0, axis=1)
        q = idx[full]
        tri = np.vstack([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
        self.tri = Triangulation(self.P[:, 0], self.P[:, 1], tri) if tri.size else None
        # each corner's share: corner, the two edge midpoints, the centre
        ctr = self.C.mean(axis=1, keepdims=True)
        nxt, prv = np.roll(self.C, -1, axis=1), np.roll(self.C, 1, axis=1)
        self.shares = np.stack([self.C, 0.5 * (self.C + nxt),
                                np.broadcast_to(ctr, self.C.shape), 0.5 * (self.C + prv)],
                               axis=2).reshape(-1, 4, 2)
        self.share_node = idx.ravel()
        lo, hi = self.C.reshape(-1, 2).min(axis=0), self.C.reshape(-1, 2).max(axis=0)
        self.limits = (lo, hi)
        # zoom on a contact zone much smaller than the face
        on = c["status"] > 0
        self.zoomed = False
        if on.any():
            zlo, zhi = self.P[on].min(axis=0), self.P[on].max(axis=0)
            span = np.maximum(zhi - zlo, 1e-12 * max(np.ptp(self.C), 1.0))
            if np.prod(span) < 0.2 * np.prod(np.maximum(hi - lo, 1e-300)):
                zlo, zhi = np.maximum(zlo - 0.6 * span, lo), np.minimum(zhi + 0.6 * span, hi)
                self.limits, self.zoomed = (zlo, zhi), True

    @property
    def aspect(self):
        lo, hi = self.limits
        w, h = hi - lo
        return w / max(h, 1e-300)

    def frame(self, ax, title):
        lo, hi = self.limits
        pad = 0.02 * (hi - lo).max()
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_xlabel(self.labels[0])
        ax.set_ylabel(self.labels[1])
        ax.set_title(title + ("\n(zoomed to the contact zone)" if self.zoomed else ""),
                     fontsize=10)
        clamped = self.share_node < 0
        if clamped.any():
            ax.add_collection(PolyCollection(self.shares[clamped], facecolor="white",
                                             edgecolor="0.5", hatch="///", linewidth=0.3))

    def field(self, fig, ax, values, title, label, cmap="viridis", vmin=None, vmax=None):
        """values at the contact nodes, drawn on the face, with a colour bar in ax.cax."""
        self.frame(ax, title)
        if self.tri is None:
            return
        lo, hi = self.limits                    # the colour range of what is shown
        seen = np.all((self.P >= lo) & (self.P <= hi), axis=1)
        shown = values[seen] if seen.any() else values
        vmin = np.min(shown) if vmin is None else vmin
        vmax = np.max(shown) if vmax is None else vmax
        if vmax <= vmin:
            vmax = vmin + max(abs(vmin), 1.0) * 1e-12 + 1e-300
        m = ax.tripcolor(self.tri, values, shading="gouraud", cmap=cmap, vmin=vmin, vmax=vmax)
        # faces with a clamped corner: each contact node's share in its own value
        part = (self.share_node >= 0) & np.repeat(~self.full, 4)
        if part.any():
            ax.add_collection(PolyCollection(self.shares[part],
                                             array=values[self.share_node[part]], cmap=cmap,
                                             norm=m.norm, edgecolor="face", linewidth=0.2))
        ax.cax.set_visible(True)
        fig.colorbar(m, cax=ax.cax, label=label)


def _no_friction(face, ax, title):
    face.frame(ax, title)
    lo, hi = face.limits
    ax.text(*(0.5 * (lo + hi)), "F = 0 on the whole face:\nno friction", ha="center",
            va="center", fontsize=12, color="0.3")


def _panels(face, n=2):
    """A figure with n panels, side by side for a squarish face, stacked for a long one.

    A fixed layout in inches (each panel: its titles above, the axes, a colour-bar slot
    ax.cax, hidden until a field is drawn, then the axis labels and a legend's room below):
    matplotlib's constrained layout measured every tick label again for each figure and
    took half of the figures' time."""
    a = face.aspect
    stacked = a >= 1.6
    W = 6.8 if stacked else 3.6                       # the axes, inches
    H = min(W / max(a, 1e-3), 9.0)
    L, CB, R, T, B, TOP = 0.75, 0.35, 0.95, 0.75, 0.95, 0.4
    pw, ph = L + W + CB + R, T + H + B                # one panel's cell
    cols, rows = (1, n) if stacked else (n, 1)
    fw, fh = cols * pw, rows * ph + TOP
    fig = plt.figure(figsize=(fw, fh))
    axes = []
    for k in range(n):
        i, j = (0, k) if stacked else (k, 0)          # column, row (from the top)
        x0, y0 = i * pw + L, fh - TOP - (j + 1) * ph + B
        ax = fig.add_axes((x0 / fw, y0 / fh, W / fw, H / fh))
        ax.cax = fig.add_axes(((x0 + W + 0.15) / fw, (y0 + 0.05 * H) / fh, 0.15 / fw,
                               0.9 * H / fh))
        ax.cax.set_visible(False)
        axes.append(ax)
    return fig, axes


def _title(fig, data, what):
    el = f" ({data['element']})" if data.get("element", "q1") != "q1" else ""
    fig.suptitle(f"{data['name']}, Nd = {data['nd']}{el}: {what}", fontsize=12,
                 y=1.0 - 0.12 / fig.get_figheight(), va="top")


def _save(fig, path):
    fig.savefig(path, dpi=DPI, format="png", pil_kwargs={"compress_level": 1})
    plt.close(fig)


def contact_status(data, face, path):
    c = data["contact"]
    fig, (a1, a2) = _panels(face)
    frictionless = not np.any(c["F"] > 0)
    face.frame(a1, "contact status\n(each node's share of the face)")
    ok = face.share_node >= 0
    st = c["status"][face.share_node[ok]].astype(int)
    area = dict((data.get("contact_result") or {}).get("area", {}))
    names, cols = list(STATUS_NAMES), list(STATUS_COLORS)
    if frictionless:                   # no stick or slip without friction: in contact or not
        st = np.minimum(st, 1)
        names, cols = ["separated", "in contact (F = 0)"], [cols[0], "#1a9641"]
        area["in contact (F = 0)"] = area.get("contact", 0.0)
    colors = np.array(cols)[st]
    a1.add_collection(PolyCollection(face.shares[ok], facecolors=colors, edgecolor="none"))
    total = area.get("separated", 0.0) + area.get("contact", 0.0) or 1.0
    handles = [Patch(color=col, label=f"{nm}: area {area.get(nm, 0.0):.4g} "
                     f"({100 * area.get(nm, 0.0) / total:.0f}%)")
               for nm, col in zip(names, cols)]
    if (~ok).any():
        handles.append(Patch(facecolor="white", edgecolor="0.5", hatch="///",
                             label="clamped (no contact condition)"))
    a1.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2,
              fontsize=8, frameon=False)
    title = "friction use |σ_τ| / (F g)\n(1: at the Coulomb bound)"
    if frictionless:
        _no_friction(face, a2, title)
    else:
        face.field(fig, a2, c["friction_use"], title, "|σ_τ| / (F g)", cmap="magma",
                   vmin=0.0, vmax=max(1.0, c["friction_use"].max()))
    _title(fig, data, "where the body sticks and slips")
    _save(fig, path)


def contact_pressure(data, face, path):
    c = data["contact"]
    fig, (a1, a2) = _panels(face)
    res = data.get("contact_result") or {}
    face.field(fig, a1, c["pressure"], f"normal pressure g = -σ_ν\n(resultant N = "
               f"{res.get('normal', float('nan')):.4g})", "g [stress]", cmap="viridis",
               vmin=0.0)
    title = (f"friction force |σ_τ|, arrows: its direction\n(resultant T = "
             f"{res.get('tangential', float('nan')):.4g})")
    if not np.any(c["F"] > 0):
        _no_friction(face, a2, title)
        _title(fig, data, "contact tractions")
        _save(fig, path)
        return
    face.field(fig, a2, c["friction"], title, "|σ_τ| [stress]", cmap="inferno", vmin=0.0)
    n = data["normal"] / np.linalg.norm(data["normal"])
    Q = basis(n)
    t = c["traction"] @ Q[:2].T                               # tangential traction (t1, t2)
    big = np.linalg.norm(t, axis=1) > 1e-3 * max(np.abs(t).max(), 1e-300)
    sel = np.flatnonzero(big)
    if sel.size > 400:
        sel = sel[:: int(np.ceil(sel.size / 400))]
    if sel.size:
        d = t[sel] / np.linalg.norm(t[sel], axis=1, keepdims=True)
        a2.quiver(face.P[sel, 0], face.P[sel, 1], d[:, 0], d[:, 1], color="cyan",
                  angles="xy", pivot="mid", width=0.003, headwidth=3.5)
    _title(fig, data, "contact tractions")
    _save(fig, path)


def contact_displacement(data, face, path):
    c = data["contact"]
    fig, (a1, a2) = _panels(face)
    face.field(fig, a1, c["tangential_displacement"], "tangential displacement |u_τ|",
               "|u_τ| [length]", cmap="viridis", vmin=0.0)
    face.field(fig, a2, c["normal_displacement"], "-u_ν = u · n\n(> 0: away from the "
               "foundation)", "-u_ν [length]", cmap="cividis")
    _title(fig, data, "displacement on the contact face")
    _save(fig, path)


def _nice(x):
    """The largest 1, 2 or 5 x 10^k not above x."""
    if not np.isfinite(x) or x <= 0:
        return 1.0
    e = np.floor(np.log10(x))
    m = x / 10 ** e
    return float((5 if m >= 5 else 2 if m >= 2 else 1) * 10 ** e)


def body_von_mises(data, path):
    peak = data.get("von_mises_max") or {}
    return _body(data, path, data["surface"]["von_mises"], "turbo",
                 "von Mises stress (cell mean) [stress]", "von Mises stress", peak)


def body_error_indicator(data, path):
    info = data.get("error_indicator") or {}
    return _body(data, path, data["surface"]["error_indicator"], "magma",
                 "||u_h - P u_2h||_a on the cell [energy^1/2]",
                 f"where the error lives (the last refinement's change; relative "
                 f"{100 * (info.get('relative') or 0.0):.2g} % of ||u||_a)",
                 info.get("max") or {})


def _body(data, path, vm, cmap, label, what, peak):
    """The deformed body's surface coloured by a cell field vm (f,)."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection
    s = data["surface"]
    X, U = s["X"], s["U"]
    pts = X.reshape(-1, 3)
    size = np.linalg.norm(np.ptp(pts, axis=0))
    umax = np.linalg.norm(U.reshape(-1, 3), axis=1).max() if U.size else 0.0
    scale = _nice(0.08 * size / umax) if umax > 0 else 1.0
    Y = X + scale * U
    fig = plt.figure(figsize=(9.0, 5.6))
    ax = fig.add_axes([0.0, 0.0, 0.84, 0.86], projection="3d")
    cax = fig.add_axes([0.86, 0.18, 0.018, 0.55])
    norm = plt.Normalize(vmin=float(vm.min()) if vm.size else 0.0,
                         vmax=float(vm.max()) if vm.size else 1.0)
    cmap = plt.get_cmap(cmap)
    coll = Poly3DCollection(Y, facecolors=cmap(norm(vm)), edgecolor=(0, 0, 0, 0.25),
                            linewidth=0.2)
    ax.add_collection3d(coll)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    for a in range(3):                              # the undeformed bounding box, dashed
        for b in (lo, hi):
            for c in (lo, hi):
                p0, p1 = lo.copy(), hi.copy()
                o = [k for k in range(3) if k != a]
                p0[o[0]] = p1[o[0]] = b[o[0]]
                p0[o[1]] = p1[o[1]] = c[o[1]]
                ax.plot(*zip(p0, p1), color="0.4", linestyle="--", linewidth=0.6)
    ylo, yhi = np.minimum(Y.reshape(-1, 3).min(axis=0), lo), \
        np.maximum(Y.reshape(-1, 3).max(axis=0), hi)
    ax.set_xlim(ylo[0], yhi[0])
    ax.set_ylim(ylo[1], yhi[1])
    ax.set_zlim(ylo[2], yhi[2])
    ax.set_box_aspect(np.maximum(yhi - ylo, 0.05 * (yhi - ylo).max()), zoom=0.98)
    ax.view_init(elev=22, azim=-58)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, cax=cax, label=label)
    where = peak.get("location")
    loc = (f"; max {peak['value']:.4g} at ({', '.join(f'{c:.3g}' for c in where)})"
           if where else "")
    ax.set_title(f"deformed body, displacement magnified x {scale:g} (max |u| = "
                 f"{umax:.3g}){loc}\ndashed: the undeformed bounding box; {UNITS}",
                 fontsize=9)
    _title(fig, data, what)
    _save(fig, path)
    return scale


def load_path(data, path):
    steps = data["steps"]
    t = np.array([s["t"] for s in steps])
    N = np.array([s["normal"] for s in steps])
    T = np.array([s["tangential"] for s in steps])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11.0, 4.4))
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.12, top=0.84, wspace=0.25)
    a1.plot(t, N, "o-", label="normal N = n · ΣR")
    a1.plot(t, T, "s-", label="tangential |T|")
    F = data["friction"]
    if isinstance(F, (int, float)) and F > 0:
        a1.plot(t, F * N, "k--", linewidth=0.8, label=f"F N (F = {F:g}): the friction limit")
    a1.set_xlabel("load parameter t")
    a1.set_ylabel("force [stress x length²]")
    a1.set_title("contact resultants", fontsize=10)
    a1.grid(alpha=0.3)
    a1.legend(fontsize=8)
    for k, (name, col) in enumerate(zip(STATUS_NAMES, STATUS_COLORS)):
        if k:
            a2.plot(t, [s["area"][name] for s in steps], "o-", color=col, label=name)
    a2.plot(t, [s["area"]["contact"] for s in steps], "k--", linewidth=0.8,
            label="in contact")
    a2.set_xlabel("load parameter t")
    a2.set_ylabel("area [length²]")
    a2.set_title("stick and slip areas", fontsize=10)
    a2.grid(alpha=0.3)
    a2.legend(fontsize=8)
    _title(fig, data, "along the load path")
    _save(fig, path)


def _part(data, k, part):
    """The figures' data of contact part k alone (several bodies: each pair's slave face and
    each face on the foundation apart; drawn together, the faces of a body pressed from
    both sides would overlap): its faces, the nodes on them, its normal and resultant."""
    faces = data["contact_faces"][data["contact_face_parts"] == k]
    c = data["contact"]
    idx = _match(faces.reshape(-1, 3), c["coordinates"])
    nodes = np.unique(idx[idx >= 0])
    return dict(data, contact={key: v[nodes] for key, v in c.items()}, contact_faces=faces,
                normal=np.asarray(part["normal"], dtype=float),
                contact_result=part["result"], name=f"{data['name']} ({part['name']})")


def write_all(data, outdir, target=lambda p: p):
    """Every figure this run has, into outdir (each file at target(path): the staged
    temporary name). Returns the file names and the body's magnification."""
    names, scale = [], None
    if data["contact"] is not None and data["contact"]["coordinates"].shape[0]:
        views = [(data, "")] if not data.get("contact_parts") else \
            [(_part(data, k, p), "_" + p["name"]) for k, p in enumerate(data["contact_parts"])]
        for d, suffix in views:
            if not d["contact"]["coordinates"].shape[0]:
                continue
            face = Face(d)
            for name, draw in (("contact_status", contact_status),
                               ("contact_pressure", contact_pressure),
                               ("contact_displacement", contact_displacement)):
                draw(d, face, target(os.path.join(outdir, name + suffix + ".png")))
                names.append(name + suffix + ".png")
    if data["surface"]["X"].shape[0]:
        scale = body_von_mises(data, target(os.path.join(outdir, "body_von_mises.png")))
        names.append("body_von_mises.png")
        if data["surface"].get("error_indicator") is not None:
            body_error_indicator(data, target(os.path.join(outdir,
                                                           "body_error_indicator.png")))
            names.append("body_error_indicator.png")
    if len(data["steps"]) > 1:
        load_path(data, target(os.path.join(outdir, "load_path.png")))
        names.append("load_path.png")
    return names, scale
