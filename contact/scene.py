"""Scenes: YAML files giving the defaults of a run; the options database overrides them.

Named options: -scene FILE, -nd N, -friction F, -young E, -poisson NU, -uzawa_r R,
-load_steps N, -output_dir DIR, and the loop tolerances -apg_rtol, -uzawa_rtol, -fp_rtol.
Any other scalar of the scene: -scene_<path with underscores>, e.g.
-scene_boundary_top_traction_2 -40  or  -scene_mesh_upper_0 4.0.
"""
import copy
import difflib
import math
import os
import re
import reprlib

import yaml
from petsc4py import PETSc

from contact import expression, options, scene_bodies, scene_grading

#: named options -> path in the scene (declared in the option registry, options.py)
NAMED = options.NAMED

#: the paper's beam, shipped with the package (runs/paper_beam.yaml links to it), so an
#: installed contact-solve has its default scene outside the source tree
DEFAULT_SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data",
                             "paper_beam.yaml")

PART_TYPES = ("dirichlet", "contact", "traction", "pressure", "symmetry")
MESH_TYPES = ("box", "file", "gmsh")

#: the keys a scene may have, per section (anything else is a typo or unsupported)
SCHEMA = {
    None: ("name", "description", "mesh", "material", "body_force", "boundary", "contact",
           "solver", "loading", "bodies"),
    "mesh": ("type", "lower", "upper", "cells_per_nd", "nd", "file", "parameters", "rotate",
             "element", "grading", "bodies"),
    "grading": ("x", "y", "z"), "grading axis": ("bump", "progression", "points"),
    "rotate": ("axis", "degrees", "origin"),
    "material": ("young", "poisson"),
    "contact": ("friction", "foundation", "gap"),
    "foundation": ("point", "normal"),
    "loading": ("steps",),
    "solver": ("uzawa_r", "apg_rtol", "uzawa_rtol", "fp_rtol", "ssn_rtol", "apg_max_it",
               "uzawa_max_it", "fp_max_it", "ssn_max_it", "newton_rtol", "newton_max_it",
               "mode", "uzawa_inner",
               "c2f_levels", "check_tol"),
    "part": ("plane", "physical", "type", "traction", "pressure", "components",
             "displacement", "ramp"),
    "body part": ("plane", "physical", "type", "traction", "pressure", "components",
                  "displacement", "ramp", "body", "master", "friction"),
}
AXES = {"x": 0, "y": 1, "z": 2}


#: what a scene file may hold (README: Errors), checked before any value is built from it:
#: its bytes; its nodes (scalars, lists, mappings), as written and as if every alias were
#: a copy of what it names; lists and mappings nested in each other; items in one of them
MAX_BYTES, MAX_NODES, MAX_DEPTH, MAX_ITEMS = 1 << 18, 20_000, 32, 10_000


class SceneError(ValueError):
    """Bad scene file or option value."""


class _Loader(yaml.SafeLoader):
    """YAML 1.1 reads 1e8 or 21.19e4 as strings; read them as floats like YAML 1.2 does.
    Bounded while composing (PyYAML's composer recurses; ~20 us a node), then as composed,
    aliases expanded (_bounded), before a value is built."""

    depth = nodes = 0

    def compose_node(self, parent, index):
        opens = self.check_event(yaml.SequenceStartEvent, yaml.MappingStartEvent)
        self.depth, self.nodes = self.depth + opens, self.nodes + 1
        if self.depth > MAX_DEPTH or self.nodes > MAX_NODES:
            raise SceneError(f"{_DEEP if self.depth > MAX_DEPTH else _MANY} (line "
                             f"{self.peek_event().start_mark.line + 1})")
        try:
            return super().compose_node(parent, index)
        finally:
            self.depth -= opens

    def construct_document(self, node):
        _bounded(node, {})
        return super().construct_document(node)


_DEEP = f"nests lists and mappings more than {MAX_DEPTH} deep"
_MANY = f"holds more than {MAX_NODES} values, an alias counted as a copy of what it names"
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?(?:[eE][-+]?[0-9]+)$""", re.X),
    list("-+0123456789"))


def _bounded(node, done, inside=frozenset(), depth=1):
    """(nodes, depth) of a composed node expanded, each node walked once (`done`), so nine
    lines of aliases that expand to 10^9 nodes cost nine lines. Refuses a node inside
    itself (`inside`: the ones above it) and the limits MAX_*."""
    if isinstance(node, yaml.ScalarNode):
        return 1, 0
    where = f" (line {node.start_mark.line + 1})"
    if id(node) in inside:
        raise SceneError(f"holds an alias inside the list or mapping it names{where}")
    if depth > MAX_DEPTH or id(node) in done and depth + done[id(node)][1] - 1 > MAX_DEPTH:
        raise SceneError(_DEEP + where)
    if len(node.value) > MAX_ITEMS:
        raise SceneError(f"has a list or mapping of more than {MAX_ITEMS} items{where}")
    if id(node) not in done:
        kids = node.value if isinstance(node, yaml.SequenceNode) else \
            [k for pair in node.value for k in pair]
        inner = inside | {id(node)}
        sub = [_bounded(k, done, inner, depth + 1) for k in kids]
        done[id(node)] = (1 + sum(n for n, _ in sub), 1 + max((d for _, d in sub), default=0))
    if done[id(node)][0] > MAX_NODES:
        raise SceneError(_MANY + where)
    return done[id(node)]


def load(path):
    """The scene file at `path` as a dict, its limits (MAX_*) checked before any value is
    built from it; a relative mesh.file (a body's too) is taken relative to the scene file."""
    try:
        with open(path, "rb") as f:
            text = f.read(MAX_BYTES + 1)
        if len(text) > MAX_BYTES:
            raise SceneError(f"is larger than {MAX_BYTES} bytes")
        data = yaml.load(text, Loader=_Loader)
    except OSError as e:
        raise SceneError(f"cannot read scene file {path}: {e.strerror}") from None
    except SceneError as e:
        raise SceneError(f"scene file {path} {e}") from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        what = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise SceneError(f"scene file {path} is not valid YAML: {what}{where}") from None
    if not isinstance(data, dict):
        raise SceneError(f"scene file {path} must hold a mapping")
    data.setdefault("name", os.path.splitext(os.path.basename(path))[0])
    mesh = data.get("mesh")
    bodies = data.get("bodies") if isinstance(data.get("bodies"), dict) else {}
    for m in [mesh] + [b.get("mesh") for b in bodies.values() if isinstance(b, dict)]:
        if isinstance(m, dict) and isinstance(m.get("file"), str):   # relative to the scene
            m["file"] = os.path.join(os.path.dirname(os.path.abspath(path)), m["file"])
    return data


def _get(d, path):
    return d if not path else _get(d[path[0]] if isinstance(d, dict) else d[int(path[0])],
                                   path[1:])


def _set(d, path, value):
    for k in path[:-1]:
        d = d.setdefault(k, {}) if isinstance(d, dict) else d[int(k)]
    if isinstance(d, list):
        d[int(path[-1])] = value
    else:
        d[path[-1]] = value


#: scene values that may be an expression in x, y, z instead of a number
EXPRESSIONS = (("contact", "friction"), ("contact", "gap"))


def _convert(old, text, name, path=()):
    try:
        if isinstance(old, bool):
            if text.lower() not in ("1", "true", "yes", "on", "0", "false", "no", "off"):
                raise ValueError(text)
            return text.lower() in ("1", "true", "yes", "on")
        if isinstance(old, int):
            return int(text)
        try:
            return float(text)
        except ValueError:
            if isinstance(old, float) and tuple(path) not in EXPRESSIONS:
                raise
            return text
    except ValueError:
        raise SceneError(f"option -{name}: cannot read {text!r} as {type(old).__name__}") from None


def from_options(opts=None):
    """The scene of this run: -scene FILE (default the paper's beam), then overrides."""
    opts = opts or PETSc.Options()
    path_ = opts.getString("scene", DEFAULT_SCENE)
    scene = copy.deepcopy(load(path_))
    #: where each expression came from, for the error messages
    sources = {p: f"{'.'.join(p)} in scene file {path_}" for p in EXPRESSIONS}
    for opt, path in NAMED.items():
        if opts.hasName(opt):
            if tuple(path) in sources:
                sources[tuple(path)] = f"option -{opt}"
            try:
                old = _get(scene, path)
            except (KeyError, IndexError, TypeError):   # not in the scene: the option's type
                old = {int: 0, bool: False, str: ""}.get(options.BY_NAME[opt].kind, 0.0)
            _set(scene, path, _convert(old, opts.getString(opt), opt, path))
    for path, old in list(options.scalars(scene)):
        name = "scene_" + "_".join(path)
        if opts.hasName(name):
            if tuple(path) in sources:
                sources[tuple(path)] = f"option -{name}"
            _set(scene, path, _convert(old, opts.getString(name), name, path))
    validate(scene, sources)
    return scene


_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = 40


def _shown(value):
    """`value` for a message, in a few words however large it is (never walked whole)."""
    if isinstance(value, (list, dict)):
        kind = "list" if isinstance(value, list) else "mapping"
        items = value.values() if isinstance(value, dict) else value
        if len(value) > 6 or any(isinstance(c, (list, dict)) for c in items):
            return f"a {kind} of {len(value)} items"
        return f"a {kind} {_REPR.repr(value)}"
    return _REPR.repr(value)


def _number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool) and \
        math.isfinite(value)


#: the kinds of the scene values an option may also give (options.py: REGISTRY)
KINDS = {int: ("an integer", lambda v: isinstance(v, int) and not isinstance(v, bool)),
         float: ("a finite number", _number), str: ("a string", lambda v: isinstance(v, str)),
         bool: ("true or false", lambda v: isinstance(v, bool))}
#: names of scene values in messages, where the path alone says little
LABELS = {("material", "young"): "Young's modulus (material.young)",
          ("material", "poisson"): "Poisson ratio (material.poisson)"}


def _kinds(scene):
    """Each value at an option's scene path is of the option's kind (friction and gap,
    numbers or expressions: _rest and _foundation), before anything reads it."""
    for o in options.REGISTRY:
        if not o.scene or tuple(o.scene) in EXPRESSIONS:
            continue
        try:
            value = _get(scene, o.scene)
        except (KeyError, IndexError, TypeError, ValueError):     # not there: a default
            continue
        words, ok = KINDS[o.kind]
        if value is not None and not ok(value):
            what = LABELS.get(tuple(o.scene), ".".join(o.scene))
            raise SceneError(f"{what} must be {words}, got {_shown(value)}")


def _positive(value, what):
    if not _number(value) or value <= 0:
        raise SceneError(f"{what} must be a positive finite number, got {_shown(value)}")


def _check_keys(d, section, where):
    allowed = SCHEMA[section]
    if not isinstance(d, dict):
        raise SceneError(f"{where} must be a mapping, got {_shown(d)}")
    for key in d:
        if key not in allowed:
            close = difflib.get_close_matches(str(key), allowed, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else \
                f" (allowed: {', '.join(allowed)})"
            raise SceneError(f"unknown key {_REPR.repr(key)} in {where}{hint}")


def _numbers(value, n, what):
    """A list of n finite numbers (not bool)."""
    if not (isinstance(value, list) and len(value) == n and
            all(_number(c) for c in value)):
        raise SceneError(f"{what} must be a list of {n} finite numbers, got {_shown(value)}")
    return value


def validate(scene, sources=None):
    """Check the keys and values a run needs; raise SceneError naming the first bad one.
    sources: where the expressions came from (path -> words), for the messages."""
    _check_keys(scene, None, "the scene")
    if "bodies" in scene:                   # several bodies (scene_bodies.py)
        scene_bodies.expand(scene)
    for section in ("mesh", "material", "contact", "solver", "loading"):
        if section in scene:
            _check_keys(scene[section], section, f"section '{section}'")
    for key in ("mesh", "material", "boundary"):
        if key not in scene:
            raise SceneError(f"scene has no '{key}' section")
    for key in ("name", "description"):
        if not isinstance(scene.get(key, ""), str):
            raise SceneError(f"{key} must be a string, got {_shown(scene[key])}")
    _kinds(scene)
    mesh = scene["mesh"]
    kind = mesh.setdefault("type", "box")
    if kind not in MESH_TYPES and not (kind == "bodies" and "bodies" in scene):
        raise SceneError(f"mesh.type must be one of {', '.join(MESH_TYPES)}, got {_shown(kind)}")
    nd = mesh.get("nd", 1)
    if not isinstance(nd, int) or isinstance(nd, bool) or nd < 1:
        raise SceneError(f"nd must be an integer >= 1 (mesh.nd), got {_shown(nd)}")
    if kind in ("file", "gmsh"):
        if not isinstance(mesh.get("file"), str):
            raise SceneError(f"mesh.file must name a mesh file ({'.geo or .msh' if kind == 'gmsh' else 'gmsh .msh, ExodusII, ...'})")
        mesh.setdefault("nd", 1)
        params = mesh.setdefault("parameters", {})
        if not isinstance(params, dict) or not all(
                isinstance(k, str) and _number(v) for k, v in params.items()):
            raise SceneError(f"mesh.parameters must map names to finite numbers, got "
                             f"{_shown(params)}")
    elif kind == "box":
        _box(mesh)
    if "rotate" in mesh:
        _rotate(mesh["rotate"])
    if "grading" in mesh:
        scene_grading.check(mesh)
    el = mesh.get("element", "auto")
    if el != "auto" and el not in options.ELEMENT_NAMES:
        raise SceneError(f"mesh.element must be auto, {', '.join(options.ELEMENT_NAMES)}, "
                         f"got {_shown(el)}")
    _material(scene["material"])
    _rest(scene)
    for path in EXPRESSIONS:
        _expression(scene, path, (sources or {}).get(path, ".".join(path)))
    return scene


def _expression(scene, path, source):
    """An expression of the scene (EXPRESSIONS) is checked against the language of
    contact/expression.py before any mesh is built (it is only evaluated at the nodes)."""
    try:
        text = _get(scene, path)
    except (KeyError, TypeError):
        return
    if not isinstance(text, str):
        return
    try:
        expression.parse(text)
    except expression.ExpressionError as e:
        shown = text if len(text) <= 60 else text[:57] + "..."
        raise SceneError(f"{source}: the expression {shown!r} {e}") from None


def _box(mesh):
    lower = _numbers(mesh.get("lower"), 3, "mesh.lower")
    upper = _numbers(mesh.get("upper"), 3, "mesh.upper")
    if not all(u > lo for lo, u in zip(lower, upper)):
        raise SceneError(f"mesh.upper must exceed mesh.lower in every direction, got "
                         f"{lower} and {upper}")
    cpn = mesh.setdefault("cells_per_nd", [1, 1, 1])
    if not (isinstance(cpn, list) and len(cpn) == 3 and
            all(isinstance(c, int) and not isinstance(c, bool) and c >= 1 for c in cpn)):
        raise SceneError(f"mesh.cells_per_nd must be 3 integers >= 1, got {_shown(cpn)}")


def _rotate(rot):
    """mesh.rotate: {axis, degrees, origin}: the mesh turned about the line through `origin`
    (default 0) along `axis` after its boundary parts are found (planes name the unrotated
    mesh; tractions, components and the foundation are in the rotated x, y, z)."""
    _check_keys(rot, "rotate", "mesh.rotate")
    ax = _numbers(rot.get("axis"), 3, "mesh.rotate.axis")
    if not any(ax):
        raise SceneError("mesh.rotate.axis must not be zero")
    deg = rot.get("degrees")
    if not _number(deg):
        raise SceneError(f"mesh.rotate.degrees must be a finite number, got {_shown(deg)}")
    _numbers(rot.setdefault("origin", [0.0, 0.0, 0.0]), 3, "mesh.rotate.origin")


def _material(mat):
    _positive(mat.get("young"), "Young's modulus (material.young)")
    if not _number(nu := mat.get("poisson")) or not -1.0 < nu < 0.5:
        raise SceneError(f"Poisson ratio (material.poisson) must be in (-1, 0.5), got {_shown(nu)}")


def _rest(scene):
    """Solver values, body force, friction and the boundary parts."""
    sol = scene.setdefault("solver", {})
    for k in ("uzawa_r", "apg_rtol", "uzawa_rtol", "fp_rtol"):
        _positive(sol.setdefault(k, options.SCENE_SOLVER_DEFAULTS[k]), f"solver.{k}")
    _numbers(scene.setdefault("body_force", [0.0, 0.0, 0.0]), 3, "body_force")
    steps = scene.setdefault("loading", {}).setdefault("steps", 1)
    if not isinstance(steps, int) or isinstance(steps, bool) or steps < 1:
        raise SceneError(f"loading.steps must be an integer >= 1, got {_shown(steps)}")
    _foundation(scene["contact"] if isinstance(scene.get("contact"), dict) else {})
    fr = scene.setdefault("contact", {}).setdefault("friction", 0.0)
    if isinstance(fr, bool) or not isinstance(fr, (int, float, str)):
        raise SceneError(f"contact.friction must be a number or an expression in x, y, z, "
                         f"got {_shown(fr)}")
    if isinstance(fr, (int, float)) and (not math.isfinite(fr) or fr < 0):
        raise SceneError(f"contact.friction must be a finite number >= 0, got {fr!r}")
    parts = scene["boundary"]
    if not isinstance(parts, dict) or not parts:
        raise SceneError(f"scene has no boundary parts (boundary: {_shown(parts)})")
    for name, part in parts.items():
        if not isinstance(name, str):
            raise SceneError(f"boundary part names must be strings, got {_shown(name)}")
        _check_keys(part, "body part" if "bodies" in scene else "part",
                    f"boundary part '{name}'")
        t = part.get("type")
        if t not in PART_TYPES:
            raise SceneError(f"boundary part {name!r}: type must be one of {PART_TYPES}, got "
                             f"{_shown(t)}")
        if ("plane" in part) == ("physical" in part):
            raise SceneError(f"boundary part {name!r}: give either plane: [x|y|z, value] or "
                             f"physical: <gmsh physical group name>")
        if "physical" in part:
            if scene["mesh"]["type"] not in ("gmsh", "bodies"):  # (bodies: scene_bodies.py)
                raise SceneError(f"boundary part {name!r}: physical names need a gmsh mesh "
                                 f"(mesh.type: gmsh), not {scene['mesh']['type']!r}")
            if not isinstance(part["physical"], (str, int)) or isinstance(part["physical"], bool):
                raise SceneError(f"boundary part {name!r}: physical must be a group name")
            part["physical"] = str(part["physical"])
        else:
            plane = part.get("plane")
            if not (isinstance(plane, list) and len(plane) == 2 and
                    isinstance(plane[0], str) and plane[0] in AXES and _number(plane[1])):
                raise SceneError(f"boundary part {name!r}: plane must be [x|y|z, finite "
                                 f"value], got {_shown(plane)}")
        if t == "traction":
            _numbers(part.get("traction"), 3, f"boundary part {name!r}: traction")
        if t == "pressure" and not _number(part.get("pressure")):
            raise SceneError(f"boundary part {name!r}: pressure must be a finite number (the "
                             f"traction -p n, n the face's outward normal), got "
                             f"{_shown(part.get('pressure'))}")
        for key in ("traction", "pressure"):
            if key in part and t != key:
                raise SceneError(f"boundary part {name!r}: {key} belongs to {key} parts, "
                                 f"not {t}")
        if t == "dirichlet":
            comps = part.setdefault("components", ["x", "y", "z"])
            if not (isinstance(comps, list) and comps and
                    all(isinstance(c, str) and c in AXES for c in comps)):
                raise SceneError(f"boundary part {name!r}: components must be among x, y, z")
            _numbers(part.setdefault("displacement", [0.0, 0.0, 0.0]), 3,
                     f"boundary part {name!r}: displacement")
        elif "displacement" in part or "components" in part:
            raise SceneError(f"boundary part {name!r}: displacement/components belong to "
                             f"dirichlet parts, not {t}")
        if "ramp" in part:
            _ramp(part, name)
    if not any(p["type"] in ("dirichlet", "symmetry", "contact") for p in parts.values()):
        raise SceneError("scene has no dirichlet (clamped), symmetry or contact part: "
                         "rigid-body motion is not excluded")


def _ramp(part, name):
    """ramp: [t0, t1], 0 <= t0 < t1 <= 1: the part's load grows from 0 at t0 to full at t1."""
    if part["type"] not in ("traction", "pressure", "dirichlet"):
        raise SceneError(f"boundary part {name!r}: ramp belongs to traction, pressure and "
                         f"dirichlet parts, not {part['type']}")
    r = _numbers(part["ramp"], 2, f"boundary part {name!r}: ramp")
    if not 0.0 <= r[0] < r[1] <= 1.0:
        raise SceneError(f"boundary part {name!r}: ramp [t0, t1] needs 0 <= t0 < t1 <= 1 "
                         f"(load parameter), got {r!r}")
    part["ramp"] = [float(r[0]), float(r[1])]


def ramp_factor(ramp, t):
    """A part's factor at load parameter t: 0 before t0, 1 after t1, linear between."""
    t0, t1 = ramp
    return min(1.0, max(0.0, (t - t0) / (t1 - t0)))


def _foundation(contact):
    """contact.foundation: the plane through `point`, `normal` into the body (0, e_z)."""
    fd = contact.setdefault("foundation", {})
    _check_keys(fd, "foundation", "contact.foundation")
    _numbers(fd.setdefault("point", [0.0, 0.0, 0.0]), 3, "contact.foundation.point")
    n = _numbers(fd.setdefault("normal", [0.0, 0.0, 1.0]), 3, "contact.foundation.normal")
    if not any(n):
        raise SceneError(f"contact.foundation.normal must not be zero, got {n!r}")
    gap = contact.get("gap")
    if gap is not None and (isinstance(gap, bool) or not isinstance(gap, (int, float, str))
                            or (isinstance(gap, float) and not math.isfinite(gap))):
        raise SceneError(f"contact.gap must be a number or an expression in x, y, z, "
                         f"got {_shown(gap)}")


def foundation_normal(scene):
    """The foundation's unit normal n (validated by `validate`)."""
    n = scene.get("contact", {}).get("foundation", {}).get("normal", [0.0, 0.0, 1.0])
    norm = math.sqrt(sum(float(c) ** 2 for c in n))
    return [float(c) / norm for c in n]


def turned(scene, axis, degrees):
    """(the validated scene turned by `degrees` about `axis` through the origin, R): mesh,
    tractions, body force, foundation; its answer is u_turned(R X) = R u(X)."""
    from contact.geometry import rotation, turn_scene
    sc, R = copy.deepcopy(scene), rotation(axis, degrees)
    if "rotate" in sc["mesh"]:
        raise SceneError("turned: the scene's mesh is already rotated")
    turn_scene(sc, axis, degrees, R)
    return validate(sc), R
