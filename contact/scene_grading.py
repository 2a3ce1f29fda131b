"""mesh.grading (and a body's grading), checked: scene.validate and scene_bodies call `check`.

    grading: {x: {bump: 0.08}, z: {progression: 4.0}}      fixed maps (mesh/grading.py)
    grading: {x: {points: [0, 0.02, 0.06, ..., 1]}}       phi at t = k / K, by hand or as a
                                                          run wrote it (summary.json grading)
    grading: auto             every axis from the run's error indicator (contact/adapt.py)
    grading: {x: auto, z: {bump: 0.2}}                    x from the indicator, z fixed

`-mesh_grading auto` makes every axis auto from the command line (options.py).
A gmsh or file mesh takes a grading too where it is a tensor-product hexahedral mesh of a
box (mesh/grading.py place_lattice: its planes re-placed; refused otherwise).
"""
from contact import scene as _scene     # (read when called: scene.py imports this first)

AUTO = "auto"
#: the range of bump and progression, and the smallest step of a points list
RANGE, MIN_STEP = (1e-3, 1e3), 1e-6


def check(mesh, where="mesh.grading", auto=True):
    """The grading of a box mesh or a body (mesh: {type: box, grading}) in place (numbers
    as floats), or a SceneError naming the first bad value. auto: whether `auto` is
    allowed."""
    SceneError, shown = _scene.SceneError, _scene._shown
    if mesh["type"] not in ("box", "gmsh", "file"):
        raise SceneError(f"{where} needs a box, gmsh or file mesh, not {mesh['type']!r}")
    g = mesh["grading"]
    if g == AUTO or (isinstance(g, dict) and AUTO in g.values()):
        if not auto:
            raise SceneError(f"{where}: auto is not allowed here")
        if g == AUTO:
            return
    _scene._check_keys(g, "grading", where)
    for axis, spec in g.items():
        if spec == AUTO:
            continue
        _scene._check_keys(spec, "grading axis", f"{where}.{axis}")
        (kind, v), = spec.items() if len(spec) == 1 else [("bump|progression|points (one)",
                                                           spec)]
        if kind == "points":
            spec[kind] = _points(v, f"{where}.{axis}.points")
        elif not _scene._number(v) or not RANGE[0] <= v <= RANGE[1]:
            raise SceneError(f"{where}.{axis}.{kind} must be a number in [0.001, 1000], "
                             f"got {shown(v)}")
        else:
            spec[kind] = float(v)


def _points(v, where):
    if not (isinstance(v, list) and len(v) >= 2 and all(_scene._number(p) for p in v)
            and v[0] == 0 and v[-1] == 1 and
            all(b - a >= MIN_STEP for a, b in zip(v[:-1], v[1:]))):
        raise _scene.SceneError(f"{where} must be numbers increasing from 0 to 1 (steps of "
                                f"at least {MIN_STEP:g}), got {_scene._shown(v)}")
    return [float(p) for p in v]


def auto_axes(mesh):
    """The axes ("x", "y", "z") whose grading the run chooses (mesh.grading auto)."""
    g = mesh.get("grading")
    if g == AUTO:
        return list("xyz")
    return [a for a, spec in (g or {}).items() if spec == AUTO] if isinstance(g, dict) \
        else []
