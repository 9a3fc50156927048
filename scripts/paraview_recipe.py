"""The README's ParaView recipe, run by ParaView's own Python (not by CI; needs Debian's `paraview`
and `python3-paraview`, and `xvfb` without a display):

    xvfb-run -a pvpython scripts/paraview_recipe.py results/demo/fields/emf_sheet_bulge_sheet.xdmf [OUT.png]

Open the field file (one source), Warp By Vector with `displacement_m` (scale 1), colour the warped
output by `von_mises_Pa` at the last time, save a screenshot (default: next to the file, `<file>.png`).
It prints what a user would check: the reader, one unstructured grid, the exact times, the arrays of
the warped output (every field, not only the displacement), that the warp moved the points by the
displacement, the von Mises range and the stress tensor's components.
"""
import sys

from paraview import servermanager
from paraview.simple import (ColorBy, GetActiveViewOrCreate, GetAnimationScene, GetColorTransferFunction,
                             OpenDataFile, SaveScreenshot, Show, WarpByVector)
from vtk.numpy_interface import dataset_adapter as dsa

path = sys.argv[1]
png = sys.argv[2] if len(sys.argv) > 2 else path.rsplit(".", 1)[0] + "_paraview.png"

# File > Open, Apply (ParaView picks Xdmf3ReaderS for .xdmf; choose it if asked)
src = OpenDataFile(path)
times = list(src.TimestepValues)
print("reader:", src.GetXMLName())
print("times [s]:", times)
t_last = times[-1]
scene = GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
scene.AnimationTime = t_last  # the time controls: last frame
src.UpdatePipeline(t_last)
raw = servermanager.Fetch(src)
print("output:", raw.GetClassName(), "points", raw.GetNumberOfPoints(), "cells", raw.GetNumberOfCells())
print("point arrays:", list(src.PointData.keys()), " cell arrays:", list(src.CellData.keys()))
stress = src.CellData["stress_Pa"]
print("stress_Pa components:", stress.GetNumberOfComponents(),
      [stress.GetComponentName(i) for i in range(stress.GetNumberOfComponents())])

# Filters > Warp By Vector: Vectors displacement_m, Scale Factor 1, Apply
warp = WarpByVector(Input=src)
warp.Vectors = ["POINTS", "displacement_m"]
warp.ScaleFactor = 1.0
warp.UpdatePipeline(t_last)
out = dsa.WrapDataObject(servermanager.Fetch(warp))
ref = dsa.WrapDataObject(raw)
moved = abs(out.Points - (ref.Points + ref.PointData["displacement_m"])).max()
print("warped:", out.VTKObject.GetClassName(), "arrays:", list(out.PointData.keys()) + list(out.CellData.keys()))
print("max |warped point - (point + displacement_m)| [m]:", float(moved))
print("max |displacement_m| [m]:", float(abs(ref.PointData["displacement_m"]).max()))

# colour by von_mises_Pa (cells), scalar bar on
view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [1200, 600]
disp = Show(warp, view)
ColorBy(disp, ("CELLS", "von_mises_Pa"))
disp.RescaleTransferFunctionToDataRange(True, False)
disp.SetScalarBarVisibility(view, True)
lut = GetColorTransferFunction("von_mises_Pa")
vm = out.CellData["von_mises_Pa"]
print("von_mises_Pa range [Pa]: %.6g .. %.6g (colour map %.6g .. %.6g)" % (
    float(vm.min()), float(vm.max()), lut.RGBPoints[0], lut.RGBPoints[-4]))
view.ResetCamera()
SaveScreenshot(png, view, ImageResolution=[1200, 600])
print("screenshot:", png)
