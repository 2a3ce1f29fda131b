"""Installed use: `pip install .` (not editable) into a fresh venv that sees the system's
PETSc, then `contact-solve -nd 3 -output_dir D` from another folder solves Nd = 3 into D
with the default scene shipped as package data (no source tree on the path)."""
import glob
import json
import os
import shutil
import subprocess
import sys
import sysconfig

import pytest
from conftest import ROOT, skip_in_parallel

ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
ENV.pop("OMPI_COMM_WORLD_SIZE", None)
ENV.pop("PYTHONPATH", None)


@pytest.mark.slow
@skip_in_parallel
def test_installed_contact_solve_reads_its_command_line(tmp_path):
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)],
                   check=True, capture_output=True)
    py = venv / "bin" / "python"
    site = subprocess.run([str(py), "-c", "import sysconfig; "
                           "print(sysconfig.get_paths()['purelib'])"], check=True,
                          capture_output=True, text=True).stdout.strip()
    # petsc4py as this interpreter finds it (Debian's lives under PETSc's own tree: the
    # Makefile's .pth; a user's own build: its PYTHONPATH), and nothing of the checkout
    here = sysconfig.get_paths()["purelib"]
    for pth in glob.glob(os.path.join(here, "debian_petsc4py.pth")):
        shutil.copy(pth, site)
    src = tmp_path / "src"
    shutil.copytree(ROOT, src, symlinks=True, ignore=shutil.ignore_patterns(
        ".git", ".venv", ".gpu", ".dev", "runs", "tests", "*.egg-info", "__pycache__"))
    p = subprocess.run([str(py), "-m", "pip", "install", "-q", "--no-deps",
                        "--no-build-isolation", "--no-index", str(src)], env=ENV,
                       capture_output=True, text=True, cwd=tmp_path)
    if p.returncode and "setuptools" in p.stderr:
        pytest.skip("no setuptools for a non-editable install here")
    assert p.returncode == 0, p.stderr[-2000:]
    shutil.rmtree(src)                               # nothing left but the installed copy
    work = tmp_path / "elsewhere"
    work.mkdir()
    out = tmp_path / "D"
    p = subprocess.run([str(venv / "bin" / "contact-solve"), "-nd", "3", "-output_dir",
                        str(out), "-output_formats", "json"], env=ENV, capture_output=True,
                       text=True, cwd=work, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    with open(out / "summary.json") as f:
        s = json.load(f)
    assert s["nd"] == 3 and s["scene"] == "paper_beam"
    assert not (work / "runs").exists()              # nothing written where it ran
    import_path = subprocess.run([str(py), "-c", "import contact; print(contact.__file__)"],
                                 env=ENV, capture_output=True, text=True, cwd=work).stdout
    assert str(venv) in import_path                  # the installed package, not the tree
