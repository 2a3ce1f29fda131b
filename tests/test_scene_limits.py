"""What a scene file may hold is bounded (scene.MAX_*: bytes, values with aliases expanded,
nesting, items in one list) and checked before any value is built from it; every value is
type-checked before use, the message naming its key in one short line (README: Errors).
The command line's side (one line, exit 1, time and memory of a run) is in test_bad_input."""
import glob
import os
import time
import tracemalloc

import pytest
import yaml
from conftest import PAPER, ROOT

from contact import scene as scenes


def paper_text():
    with open(PAPER) as f:
        return f.read()


def laughs(levels=9):
    """The paper's scene with mesh.nd an alias of `levels` lines of anchors, each a list
    of ten aliases of the one before ("billion laughs": 10^9 values expanded)."""
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"a{k}: &a{k} [" + ", ".join([f"*a{k - 1}"] * 10) + "]" for k in range(1, levels)]
    return "\n".join(lines) + "\n" + paper_text().replace("  nd: 10\n",
                                                          f"  nd: *a{levels - 1}\n")


#: (id, text of the scene file, fragment of the one-line error)
LIMITS = [
    ("billion-laughs", laughs(), f"holds more than {scenes.MAX_NODES} values"),
    ("deep-flow", paper_text() + "description: " + "[" * 10000 + "]" * 10000 + "\n",
     f"nests lists and mappings more than {scenes.MAX_DEPTH} deep"),
    ("deep-block", paper_text() + "".join("  " * i + f"k{i}:\n" for i in range(40)),
     f"nests lists and mappings more than {scenes.MAX_DEPTH} deep"),
    ("deep-aliases", paper_text() + "".join(
        f"a{i}: &a{i} [{f'*a{i - 1}' if i else 1}]\n" for i in range(40)),
     f"nests lists and mappings more than {scenes.MAX_DEPTH} deep"),
    ("huge-list", paper_text() + "description: [" + ", ".join(["1"] * 10001) + "]\n",
     f"has a list or mapping of more than {scenes.MAX_ITEMS} items"),
    ("too-big", paper_text() + "#" + "x" * scenes.MAX_BYTES + "\n",
     f"is larger than {scenes.MAX_BYTES} bytes"),
    ("self-alias", paper_text() + "x: &x [1, *x]\n",
     "holds an alias inside the list or mapping it names"),
    ("self-alias-mapping", paper_text() + "x: &x {a: {b: *x}}\n",
     "holds an alias inside the list or mapping it names"),
]


@pytest.mark.parametrize("case,text,msg", LIMITS, ids=[c[0] for c in LIMITS])
def test_limits_refused_at_once_in_little_memory(tmp_path, case, text, msg):
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    t = time.perf_counter()
    with pytest.raises(scenes.SceneError) as e:
        scenes.validate(scenes.load(str(path)))
    wall = time.perf_counter() - t                     # (here: 0.15 s at most, unloaded)
    assert msg in str(e.value) and "\n" not in str(e.value), str(e.value)
    assert wall < 1.0, wall
    tracemalloc.start()                                # (slows it down: timed apart)
    with pytest.raises(scenes.SceneError):
        scenes.validate(scenes.load(str(path)))
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 64 * 2 ** 20, peak                   # the file, its nodes: a few MB


def test_the_shipped_scenes_are_within_the_limits():
    files = glob.glob(os.path.join(ROOT, "runs", "scenes", "*.yaml")) + [
        os.path.join(ROOT, "contact", "data", "paper_beam.yaml"), PAPER]
    for f in files:
        scenes.validate(scenes.load(f))


def test_aliases_within_the_limits_are_read(tmp_path):
    """Anchors, aliases and merge keys a scene may well use still work."""
    text = paper_text().replace("lower: [0.0, 0.0, 0.0]", "lower: &zero [0.0, 0.0, 0.0]")
    text = text.replace("body_force: [0.0, 0.0, 0.0]", "body_force: *zero")
    text = text.replace("  end:     {plane: [x, 3.0], type: traction, ",
                        "  end:     {<<: &load {type: traction}, plane: [x, 3.0], ")
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    sc = scenes.validate(scenes.load(str(path)))
    assert sc["body_force"] == [0.0, 0.0, 0.0] and sc["boundary"]["end"]["type"] == "traction"


def _edit(value, *keys):
    def edit(sc):
        d = sc
        for k in keys[:-1]:
            d = d.setdefault(k, {})
        d[keys[-1]] = value
    return edit


#: (a value where it does not belong, the scene path, the message's start)
TYPES = [
    ([1, 2], ("mesh", "nd"), "mesh.nd must be an integer, got a list [1, 2]"),
    (2.0, ("mesh", "nd"), "mesh.nd must be an integer, got 2.0"),
    ({"a": 1}, ("material", "young"),
     "Young's modulus (material.young) must be a finite number, got a mapping"),
    ([0.3], ("material", "poisson"), "Poisson ratio (material.poisson) must be a finite"),
    ({"a": 1}, ("solver", "mode"), "solver.mode must be a string, got a mapping {'a': 1}"),
    ([1, 2], ("solver", "apg_max_it"), "solver.apg_max_it must be an integer, got a list"),
    ("abc", ("solver", "ssn_rtol"), "solver.ssn_rtol must be a finite number, got 'abc'"),
    (float("nan"), ("solver", "check_tol"), "solver.check_tol must be a finite number"),
    ([[1.0]], ("solver", "uzawa_r"), "solver.uzawa_r must be a finite number, got a list"),
    (["q1"], ("mesh", "element"), "mesh.element must be a string, got a list ['q1']"),
    ({"a": 1}, ("mesh", "type"), "mesh.type must be one of box, file, gmsh, got a mapping"),
    ([1], ("loading", "steps"), "loading.steps must be an integer, got a list [1]"),
    ({"x": 1}, ("name",), "name must be a string, got a mapping"),
    ([0.3], ("contact", "friction"), "contact.friction must be a number or an expression"),
    ({"a": 1}, ("contact", "gap"), "contact.gap must be a number or an expression"),
    ("abc", ("mesh", "lower"), "mesh.lower must be a list of 3 finite numbers, got 'abc'"),
    (5.0, ("boundary", "top", "traction"), "boundary part 'top': traction must be a list"),
    ([["x"], 0.0], ("boundary", "clamped", "plane"), "boundary part 'clamped': plane must be"),
    ([["x"]], ("boundary", "clamped", "components"), "components must be among x, y, z"),
    ([1.0] * 5000, ("boundary", "top", "traction"), "got a list of 5000 items"),
]


@pytest.mark.parametrize("value,path,msg", TYPES, ids=[".".join(t[1]) + "-" +
                                                       type(t[0]).__name__ for t in TYPES])
def test_a_value_of_the_wrong_type_is_named_in_one_short_line(tmp_path, value, path, msg):
    with open(PAPER) as f:
        sc = yaml.load(f, Loader=scenes._Loader)
    _edit(value, *path)(sc)
    p = tmp_path / "scene.yaml"
    p.write_text(yaml.safe_dump(sc))
    with pytest.raises(scenes.SceneError) as e:
        scenes.validate(scenes.load(str(p)))
    assert msg in str(e.value), str(e.value)
    assert "\n" not in str(e.value) and len(str(e.value)) < 200, str(e.value)
