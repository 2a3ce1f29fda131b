"""ParaView opens solution.xdmf (contact/io/pvview.py under pvbatch, as `make view` runs it):
every grid and field the XDMF names is found in what ParaView loaded, and it renders the
body coloured by von Mises and the contact map. Runs only where ParaView (pvbatch) and
xvfb-run are installed (`make view` installs them); serial (it launches its own runs)."""
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, skip_in_parallel

from contact.io import output

pytestmark = [skip_in_parallel,
              pytest.mark.skipif(not (shutil.which("pvbatch") and shutil.which("xvfb-run")),
                                 reason="ParaView (pvbatch) or xvfb-run not installed")]

RUNS = {"static": [], "quasi": ["-scene", os.path.join(ROOT, "runs", "scenes",
                                                      "block_shear.yaml")]}


@pytest.mark.parametrize("case", list(RUNS))
def test_paraview_reads_and_renders(tmp_path, case):
    out = tmp_path / case
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    p = subprocess.run([sys.executable, "-m", "contact", "-nd", "2", "-solver_mode", "fast",
                        *RUNS[case], "-output_dir", str(out)], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    v = subprocess.run(["xvfb-run", "-a", "-f", str(tmp_path / "Xauthority"),
                        "-s", "-screen 0 1280x1024x24", "pvbatch",
                        os.path.join(ROOT, "contact", "pvview.py"), str(out)],
                       cwd=ROOT, capture_output=True, text=True, timeout=300)
    lines = [ln for ln in v.stdout.splitlines() if ln.startswith("paraview:")]
    assert v.returncode == 0, v.stdout[-3000:] + v.stderr[-3000:]
    found = [re.search(r"grid '(\w+)'.* (\d+) of (\d+) fields found", ln) for ln in lines]
    found = {m.group(1): (int(m.group(2)), int(m.group(3))) for m in found if m}
    assert set(found) == {"body", "contact"}, lines
    n_body, n_contact = len(output.BODY), len(output.CONTACT)
    assert found["body"] == (n_body, n_body), lines
    assert found["contact"] == (n_contact, n_contact), lines
    import matplotlib.image as mpimg
    for name in ("paraview_body.png", "paraview_contact.png"):
        img = mpimg.imread(out / name)
        rgb = np.round(img[..., :3] * 255).astype(np.int64).reshape(-1, 3) @ [65536, 256, 1]
        assert np.unique(rgb).size > 50, name                # a rendering, not a blank view
