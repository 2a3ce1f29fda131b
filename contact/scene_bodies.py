"""Scenes with several bodies: the `bodies:` section, checked and expanded (scene.validate).

    bodies:
      base:  {lower: [0, 0, 0], upper: [1, 1, 0.5], cells: [5, 5, 3],
              material: {young: 1.0, poisson: 0.3}}
      punch: {lower: [0, 0, 0.5], upper: [1, 1, 1], cells: [7, 7, 4],
              material: {young: 1.0, poisson: 0.3}}
    boundary:
      bottom:    {type: dirichlet, body: base, plane: [z, 0], components: [z]}
      press:     {type: traction, body: punch, plane: [z, 1], traction: [0, 0, -0.1]}
      interface: {type: contact, body: punch, plane: [z, 0.5],
                  master: {body: base}}          # the master face: base's plane z = 0.5

Each body is a box of hexahedra (cells times the scene's nd, -nd) or a gmsh mesh (below)
with its own material; the meshes of two bodies are independent (mesh/bodies.py). A
boundary part names its body (`body:`; without it a plane part takes the faces of every
body on it: a symmetry plane).
A contact part with `master:` is a pair: its faces are the slave side, the master's are
the faces of `master.body` on `master.plane` (default: the slave's plane); the two are
coupled by the dual mortar (fem/pairs.py). A scene may have several pairs (a stack of
blocks: each interface a contact part with its master), which share no slave node and
whose slave nodes are no other pair's master nodes (checked on the mesh). A contact part
without `master:` presses its body on the rigid foundation as in a one-body scene (beside
pairs: the foundation's normal +x, +y or +z, none of its nodes a pair's slave node). This
version: q1, q2, bbar or q2p1 (a body's `element:`, else mesh.element or -element; auto, the
default: bbar for a body of nu >= 0.4, else q1), slave faces a flat side of their body
(normal to x, y or z; pairs may face different axes). With q2 a pair couples the
elements' 9-node faces (biquadratic, isoparametric, their dual basis: fem/mortar_q2.py),
whose edges must be straight seen along the pair's normal: graded bodies
and a lower_surface master on a pair along z are; a lower_surface body's side faces in a
pair along x or y are refused in one line (use q1). Bodies may mix the two: then every
body has the q2 nodes (the mesh refined once more), and a q1 body's cells are those of
that node mesh, 8 to each of its `cells` x nd (the q2 element's nodes, each eighth a q1
cell: fem/element.py); a pair may couple a q1 and a q2 face (fem/mortar.py). bbar is q1's
and q2p1 q2's, with their own element matrices (a rubber body beside steel ones).
A contact part may have its own `friction:` (a number or an expression, as
contact.friction) on its nodes.

A body may also have `grading:` (mesh.grading's syntax, on its box) and `lower_surface:
"<f(x, y)>"` (an expression): its lower face at z = lower_z + f(x, y), the shift fading
linearly to 0 at its upper face (mesh/bodies.py: body_map); planes still name the box
(`plane: [z, lower_z]` is the curved face), which a pair's master may be (not its slave).

A body may instead be read by gmsh (all hexahedra, as for a one-body gmsh scene):

      punch: {mesh: {type: gmsh, file: ../../meshes/box.geo, parameters: {z0: 0.5}},
              material: {young: 1.0, poisson: 0.3}}

(`type: file` takes a gmsh .msh, read by gmsh too; a relative file is relative to the
scene file; the parameter nd is the scene's coarse nd unless given). Its boundary parts
are its planes or its physical surface groups, `{body: punch, physical: top}` (a part on
a group names its body); a pair's master may be a group, `master: {body: NAME,
physical: GROUP}` (curved too), the slave a group or a plane that is one flat side of
its body normal to x, y or z (checked on the mesh: fem/pairs_scene.py). With a gmsh body
-nd is the coarse level's, as for one gmsh mesh: box bodies have cells x nd there, and
-mesh_refine K refines all K times (mesh/hierarchy.py). A gmsh body's place is not
checked against the other bodies' (box bodies must not overlap each other).
"""
import os

from contact import scene as _scene     # (read when called: scene.py imports this first)
import numpy as np

from contact import expression, scene_grading

BODY_KEYS = ("lower", "upper", "cells", "material", "element", "grading", "lower_surface",
             "mesh")
#: the elements of a scene with several bodies (auto: discretisation.body_elements)
BODY_ELEMENTS = ("auto", "q1", "q2", "bbar", "q2p1")


def expand(scene):
    """Check `bodies:` (boxes and gmsh bodies) and set the mesh (type bodies) and material
    (the first body's: what a one-body reader of the scene sees) sections from it;
    idempotent."""
    SceneError, shown, numbers = _scene.SceneError, _scene._shown, _scene._numbers
    bodies = scene["bodies"]
    if not isinstance(bodies, dict) or not bodies:
        raise SceneError(f"bodies must map body names to boxes, got {shown(bodies)}")
    mesh = scene.get("mesh", {})                  # (-nd, -element: mesh.nd, mesh.element)
    if not isinstance(mesh, dict) or mesh.get("type", "bodies") != "bodies" or \
            set(mesh) - {"type", "nd", "element", "bodies", "rotate"}:
        raise SceneError("a scene with bodies: has no mesh section but nd, element and rotate "
                         "(each body is its own box)")
    boxes = []
    for name, b in bodies.items():
        if not isinstance(name, str):
            raise SceneError(f"body names must be strings, got {shown(name)}")
        where = f"body {name!r}"
        if not isinstance(b, dict) or any(k not in BODY_KEYS for k in b):
            raise SceneError(f"{where} must be a mapping of {', '.join(BODY_KEYS)}, got "
                             f"{shown(b)}")
        if b.get("element", "q1") not in BODY_ELEMENTS[1:]:
            raise SceneError(f"{where}: element must be {', '.join(BODY_ELEMENTS[1:])} (each "
                             f"body its own; without it the scene's: -element, mesh.element), "
                             f"got {shown(b['element'])}")
        if "mesh" in b:
            _body_mesh(b, where)
            continue
        lo = numbers(b.get("lower"), 3, f"{where}: lower")
        hi = numbers(b.get("upper"), 3, f"{where}: upper")
        if not all(h > lo_ for lo_, h in zip(lo, hi)):
            raise SceneError(f"{where}: upper must exceed lower in every direction")
        cells = b.get("cells")
        if not (isinstance(cells, list) and len(cells) == 3 and all(
                isinstance(c, int) and not isinstance(c, bool) and c >= 1 for c in cells)):
            raise SceneError(f"{where}: cells must be 3 integers >= 1, got {shown(cells)}")
        _body_material(b, where)
        if "grading" in b:
            _body_grading(b, where)
        if "lower_surface" in b:
            _lower_surface(b, lo, hi, where)
        for other, (olo, ohi) in boxes:
            if all(max(a, c) < min(bb, d) for a, bb, c, d in zip(lo, hi, olo, ohi)):
                raise SceneError(f"bodies {other!r} and {name!r} overlap")
        boxes.append((name, (lo, hi)))
    mesh.update(type="bodies", bodies=bodies)
    mesh.setdefault("nd", 1)
    el = mesh.setdefault("element", "auto")
    if el not in BODY_ELEMENTS:
        raise SceneError(f"a scene with several bodies has the {', '.join(BODY_ELEMENTS)} "
                         f"element, got {el!r}")
    scene["mesh"] = mesh
    first = next(iter(bodies.values()))["material"]
    if scene.setdefault("material", dict(first)) != first:
        raise SceneError("a scene with bodies: gives each body its material (a material "
                         "section, -young and -poisson do not apply)")
    if isinstance(scene.get("boundary"), dict):
        check_parts(scene)


def _body_material(b, where):
    """A body's material {young, poisson} (scene._material's ranges)."""
    SceneError = _scene.SceneError
    if not isinstance(b.get("material"), dict):
        raise SceneError(f"{where}: material must be a mapping {{young, poisson}}")
    _scene._check_keys(b["material"], "material", f"{where}: material")
    _scene._material(b["material"])


def _body_mesh(b, where):
    """A gmsh body: {mesh: {type: gmsh (a .geo or .msh) or file (a .msh, read by gmsh
    too), file, parameters: {name: number}}, material}; the file must exist."""
    SceneError, shown, m = _scene.SceneError, _scene._shown, b["mesh"]
    if set(b) - {"mesh", "material", "element"}:
        raise SceneError(f"{where}: a body with a mesh has only mesh, material and element, "
                         f"not {', '.join(sorted(set(b) - {'mesh', 'material', 'element'}))}")
    if not isinstance(m, dict) or set(m) - {"type", "file", "parameters"} or \
            m.get("type") not in ("gmsh", "file") or not isinstance(m.get("file"), str):
        raise SceneError(f"{where}: mesh must be {{type: gmsh|file, file: <.geo or .msh>, "
                         f"parameters: {{...}}}}, got {shown(m)}")
    if m["type"] == "file" and not m["file"].endswith(".msh"):
        raise SceneError(f"{where}: a body's mesh of type file is a gmsh .msh (read by gmsh), "
                         f"got {m['file']!r}")
    if not os.path.isfile(m["file"]):
        raise SceneError(f"{where}: mesh file {m['file']} does not exist")
    params = m.setdefault("parameters", {})
    if not isinstance(params, dict) or not all(
            isinstance(k, str) and _scene._number(v) for k, v in params.items()):
        raise SceneError(f"{where}: mesh.parameters must map names to finite numbers, got "
                         f"{shown(params)}")
    _body_material(b, where)


def _body_grading(b, where):
    """A body's grading: mesh.grading's syntax and ranges (scene._grading) on its box."""
    try:
        scene_grading.check({"type": "box", "grading": b["grading"]})
    except _scene.SceneError as e:
        raise _scene.SceneError(f"{where}: " + str(e).replace("mesh.grading", "grading")) \
            from None


def _lower_surface(b, lo, hi, where):
    """A body's lower_surface f(x, y) (an expression, contact/expression.py): its lower
    face at z = lower_z + f, the shift fading to 0 at the upper face (mesh/bodies.py).
    Refused where f < 0 or f >= half the body's height on the lower face (sampled on a
    33 x 33 grid, its corners and edges included): the cells there would fold or flatten."""
    SceneError = _scene.SceneError
    try:
        f = expression.parse(b["lower_surface"])
        t = np.linspace(0.0, 1.0, 33)
        X, Y = np.meshgrid(lo[0] + t * (hi[0] - lo[0]), lo[1] + t * (hi[1] - lo[1]))
        v = expression.values(f, np.stack([X.ravel(), Y.ravel(), np.full(X.size, lo[2])], 1))
    except (expression.ExpressionError, ValueError, TypeError, ZeroDivisionError) as e:
        raise SceneError(f"{where}: lower_surface: {str(e).splitlines()[0]}") from None
    half = (hi[2] - lo[2]) / 2.0
    if not (np.all(np.isfinite(v)) and v.min() >= 0.0 and v.max() < half):
        raise SceneError(f"{where}: lower_surface must be >= 0 and < half the body's height "
                         f"({half:g}) on its lower face, got values in [{np.nanmin(v):g}, "
                         f"{np.nanmax(v):g}]")


def _part_friction(name, part):
    """A contact part's own friction: a number >= 0 or an expression in x, y, z (checked
    here; its values on the nodes: fem/pairs_scene.py)."""
    SceneError, fr = _scene.SceneError, part["friction"]
    where = f"boundary part {name!r}: friction"
    if part.get("type") != "contact":
        raise SceneError(f"{where} belongs to a contact part")
    if isinstance(fr, bool) or not isinstance(fr, (int, float, str)):
        raise SceneError(f"{where} must be a number or an expression in x, y, z, got "
                         f"{_scene._shown(fr)}")
    if isinstance(fr, str):
        try:
            expression.parse(fr)
        except expression.ExpressionError as e:
            raise SceneError(f"{where}: {str(e).splitlines()[0]}") from None
    elif not np.isfinite(fr) or fr < 0:
        raise SceneError(f"{where} must be a finite number >= 0, got {fr!r}")


def check_parts(scene):
    """The parts' `body` and `master` keys: known bodies, a master on a contact part only,
    two pairs never on the same two faces; SceneError naming the part. (Which nodes the
    pairs share is checked on the mesh: fem/pairs.py.)"""
    SceneError, shown, numbers = _scene.SceneError, _scene._shown, _scene._numbers
    bodies, pairs = scene["bodies"], {}
    for name, part in scene["boundary"].items():
        if isinstance(part, dict) and "friction" in part:
            _part_friction(name, part)
        if not isinstance(part, dict) or not ("body" in part or "master" in part or
                                              "physical" in part):
            continue
        if "body" in part and (not isinstance(part["body"], str) or part["body"] not in bodies):
            raise SceneError(f"boundary part {name!r}: no body {shown(part['body'])} (the "
                             f"bodies: {', '.join(bodies)})")
        if "physical" in part:
            _physical_part(name, part, bodies)
        if "master" not in part:
            continue
        m = part["master"]
        if part.get("type") != "contact" or "body" not in part:
            raise SceneError(f"boundary part {name!r}: master belongs to a contact part "
                             f"that names its body")
        if not isinstance(m, dict) or set(m) - {"body", "plane", "physical"} or \
                not isinstance(m.get("body"), str) or m["body"] not in bodies or \
                "plane" in m and "physical" in m:
            raise SceneError(f"boundary part {name!r}: master must be {{body: <one of "
                             f"{', '.join(bodies)}>, plane: [x|y|z, value] or physical: "
                             f"<group>}}, got {shown(m)}")
        if m["body"] == part["body"]:
            raise SceneError(f"boundary part {name!r}: the master is the slave's own body")
        if "physical" in m:
            _physical_part(f"{name}'s master", m, bodies)
            where = ("physical", m["physical"])
        else:
            plane = m.setdefault("plane", part.get("plane"))
            if not (isinstance(plane, list) and len(plane) == 2 and plane[0] in _scene.AXES):
                raise SceneError(f"boundary part {name!r}: master.plane must be [x|y|z, "
                                 f"value] (the slave's plane unless given)")
            numbers(plane[1:], 1, f"boundary part {name!r}: master.plane's value")
            where = tuple(plane)
        faces = frozenset([(part["body"], tuple(part.get("plane") or
                                                ("physical", part.get("physical")))),
                           (m["body"], where)])
        if faces in pairs:
            raise SceneError(f"boundary parts {pairs[faces]!r} and {name!r} pair the same "
                             f"two faces: one contact part per pair")
        pairs[faces] = name


def _physical_part(name, part, bodies):
    """A part on a gmsh physical group (`physical:`) names its body, a gmsh body (which
    groups it has is known once its mesh is read: discretisation.py)."""
    SceneError, shown = _scene.SceneError, _scene._shown
    body = part.get("body")
    if not (isinstance(body, str) and body in bodies and "mesh" in bodies[body]):
        gmsh = ", ".join(b for b, v in bodies.items() if isinstance(v, dict) and "mesh" in v)
        raise SceneError(f"boundary part {name!r}: physical names a group of a gmsh body: "
                         f"give body: <one of {gmsh or 'none'}>, got body {shown(body)}")
    if not isinstance(part["physical"], (str, int)) or isinstance(part["physical"], bool):
        raise SceneError(f"boundary part {name!r}: physical must be a group name")
    part["physical"] = str(part["physical"])
