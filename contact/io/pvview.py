"""Open a run's solution.xdmf in ParaView and render it (`make view`; run by ParaView's
own Python, not imported by the package):

    xvfb-run -a -f AUTHFILE -s "-screen 0 1280x1024x24" pvbatch contact/io/pvview.py OUTDIR

(a 24-bit screen: with xvfb-run's default 8-bit one ParaView's window creation fails now
and then, 1 run in 12 measured; an auth file of our own, -f: xvfb-run's temporary
directory sometimes fails its clean-up, exit status 5, after the work is done).

Reads OUTDIR/solution.xdmf with ParaView's "XDMF Reader" (the Xdmf3 readers also read it;
Xdmf3ReaderT drops the grid names of a temporal collection), checks that every grid and every
attribute the XDMF names (point or cell data) is found in what ParaView loaded, and writes
OUTDIR/paraview_body.png (the deformed body coloured by the von Mises stress) and
OUTDIR/paraview_contact.png (the contact face coloured by the contact status), at the
last time step of a quasi-static run. Prints one line per grid; exit status 1 when
something is missing.
"""
import os
import sys
import xml.etree.ElementTree as ET

from paraview import servermanager
from paraview.simple import (ColorBy, ExtractBlock, GetActiveViewOrCreate,
                             GetAnimationScene, GetColorTransferFunction, Hide, MergeBlocks,
                             Render, SaveScreenshot, Show, WarpByVector, XDMFReader)
from vtkmodules.vtkCommonDataModel import vtkCompositeDataSet


def expected_fields(path):
    """{grid: {(center, name)}} of the XDMF's top-level grids (collections: their steps)."""
    out = {}
    for g in ET.parse(path).getroot().findall("./Domain/Grid"):
        out[g.get("Name")] = {(a.get("Center"), a.get("Name")) for a in g.iter("Attribute")}
    return out


def blocks(data):
    """{name: dataset} of the leaves of a multiblock data set."""
    out = {}
    for i in range(data.GetNumberOfBlocks()):
        meta = data.GetMetaData(i)
        name = meta.Get(vtkCompositeDataSet.NAME()) if meta is not None else str(i)
        b = data.GetBlock(i)
        if b is not None and b.IsA("vtkMultiBlockDataSet"):
            out.update(blocks(b))
        elif b is not None:
            out[name] = b
    return out


def arrays(ds):
    pd, cd = ds.GetPointData(), ds.GetCellData()
    return ({("Node", pd.GetArrayName(i)) for i in range(pd.GetNumberOfArrays())}
            | {("Cell", cd.GetArrayName(i)) for i in range(cd.GetNumberOfArrays())})


def look(view, ds, direction, up):
    """Camera on the data set's centre from `direction`, `up` upwards."""
    b = ds.GetBounds()
    c = [0.5 * (b[2 * i] + b[2 * i + 1]) for i in range(3)]
    size = max(b[1] - b[0], b[3] - b[2], b[5] - b[4]) or 1.0
    cam = view.GetActiveCamera()
    cam.SetFocalPoint(*c)
    cam.SetPosition(*[c[i] + 10 * size * direction[i] for i in range(3)])
    cam.SetViewUp(*up)
    view.ResetCamera()


def main(outdir):
    path = os.path.abspath(os.path.join(outdir, "solution.xdmf"))
    want = expected_fields(path)
    reader = XDMFReader(FileNames=[path])
    times = list(getattr(reader, "TimestepValues", None) or [])
    t = times[-1] if times else None
    if times:
        scene = GetAnimationScene()
        scene.UpdateAnimationUsingDataTimeSteps()
        scene.AnimationTime = t
    reader.UpdatePipeline(t) if t is not None else reader.UpdatePipeline()
    got = blocks(servermanager.Fetch(reader))
    ok = True
    for grid, fields in want.items():
        if grid not in got:
            print(f"paraview: grid {grid!r} not found (blocks: {sorted(got)})")
            ok = False
            continue
        ds = got[grid]
        missing = sorted(fields - arrays(ds))
        print(f"paraview: grid {grid!r}: {ds.GetClassName()}, {ds.GetNumberOfPoints()} points, "
              f"{ds.GetNumberOfCells()} cells, {len(fields) - len(missing)} of {len(fields)} "
              f"fields found" + (f"; missing {missing}" if missing else ""))
        ok = ok and not missing
    if not ok:
        return 1

    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = [1200, 700]
    view.OrientationAxesVisibility = 1
    def grid(name):                                        # one grid of the reader's
        return MergeBlocks(Input=ExtractBlock(Input=reader, Selectors=[f"/Root/{name}"]))

    body = grid("body")
    bounds = got["body"].GetBounds()
    size = max(bounds[1] - bounds[0], bounds[3] - bounds[2], bounds[5] - bounds[4])
    umax = got["body"].GetPointData().GetArray("displacement").GetMaxNorm()
    scale = 0.08 * size / umax if umax > 0 else 1.0
    warp = WarpByVector(Input=body, Vectors=["POINTS", "displacement"], ScaleFactor=scale)
    shown = Show(warp, view)
    ColorBy(shown, ("POINTS", "von_mises"))
    shown.RescaleTransferFunctionToDataRange(True, False)
    shown.SetScalarBarVisibility(view, True)
    GetColorTransferFunction("von_mises").ApplyPreset("Turbo", True)
    look(view, got["body"], (1.0, -1.6, 0.9), (0.0, 0.0, 1.0))
    Render(view)
    SaveScreenshot(os.path.join(outdir, "paraview_body.png"), view, ImageResolution=[1200, 700])
    print(f"paraview: wrote {os.path.join(outdir, 'paraview_body.png')} (von Mises, "
          f"displacement x {scale:.3g})")
    if "contact" in got:
        Hide(warp, view)
        contact = grid("contact")
        cshown = Show(contact, view)
        ColorBy(cshown, ("POINTS", "status"))
        lut = GetColorTransferFunction("status")
        lut.InterpretValuesAsCategories = 1
        lut.Annotations = ["0", "separated", "1", "stick", "2", "slip"]
        lut.IndexedColors = [0.78, 0.78, 0.78, 0.17, 0.48, 0.71, 0.84, 0.10, 0.11]
        cshown.SetScalarBarVisibility(view, True)
        cshown.Ambient, cshown.Diffuse = 1.0, 0.0           # a map: colours unshaded
        b = got["contact"].GetBounds()                     # look along the thinnest axis
        k = min(range(3), key=lambda i: b[2 * i + 1] - b[2 * i])
        up = (0.0, 0.0, 1.0) if k != 2 else (0.0, 1.0, 0.0)
        look(view, got["contact"], tuple(1.0 if i == k else 0.0 for i in range(3)), up)
        Render(view)
        SaveScreenshot(os.path.join(outdir, "paraview_contact.png"), view,
                       ImageResolution=[1200, 700])
        print(f"paraview: wrote {os.path.join(outdir, 'paraview_contact.png')} (status: "
              f"0 separated, 1 stick, 2 slip)")
    return 0


if __name__ == "__main__":
    rc = main(sys.argv[1] if len(sys.argv) > 1 else ".")
    sys.stdout.flush()
    # skip ParaView's teardown: under Xvfb it fails (GLXBadContext) after the work is done
    os._exit(rc)
