"""The package's architecture, held: imports point down the data flow (scene and options
-> mesh -> fem -> solvers -> analysis -> io -> problem and the command line; validation
uses any), every module <= 500 lines and every class <= 350 (README: Layout)."""
import ast
import glob
import os

from conftest import ROOT

#: the layers, in the order data flows; a module may import its own layer and those before
LAYERS = {"options": 0, "scene": 0, "scene_bodies": 0, "scene_grading": 0, "adapt": 6, "expression": 0, "geometry": 0, "petsc_compat": 0,
          "resources": 0, "mesh": 1, "fem": 2, "solvers": 3, "analysis": 4, "io": 5,
          "problem": 6, "cli": 6, "__main__": 6, "__init__": 6, "validation": 7}
PACKAGE = os.path.join(ROOT, "contact")


def _modules():
    for path in sorted(glob.glob(os.path.join(PACKAGE, "**", "*.py"), recursive=True)):
        rel = os.path.relpath(path, PACKAGE)[:-3].split(os.sep)
        with open(path) as f:
            yield rel, f.read()


def _layer(parts):
    return LAYERS[parts[0]]


def test_imports_follow_the_data_flow():
    up = []
    for rel, text in _modules():
        mine = _layer(rel)
        for node in ast.walk(ast.parse(text)):
            if not (isinstance(node, ast.ImportFrom) and node.module
                    and node.module.split(".")[0] == "contact"):
                continue
            names = ([node.module.split(".")[1:]] if node.module != "contact" else
                     [[a.name] for a in node.names])
            for target in names:
                if target and mine < 7 and _layer(target) > mine:
                    up.append(f"contact/{'/'.join(rel)}.py imports contact."
                              f"{'.'.join(target)} (line {node.lineno})")
    assert up == []


def test_every_module_has_a_layer():
    for rel, _ in _modules():
        assert rel[0] in LAYERS, rel


def test_module_and_class_sizes():
    big = []
    for rel, text in _modules():
        n = len(text.splitlines())
        if n > 500:
            big.append(f"{'/'.join(rel)}.py: {n} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ClassDef) and node.end_lineno - node.lineno + 1 > 350:
                big.append(f"{'/'.join(rel)}.py: class {node.name} "
                           f"{node.end_lineno - node.lineno + 1} lines")
    assert big == []
