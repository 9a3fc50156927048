// sheet_bulge.geo -- axisymmetric flat coil + sheet + air + shell (Gmsh, OpenCASCADE kernel).
// Mesh: gmsh sheet_bulge.geo -2 -format msh22   (GetDP 3.2.0 reads MSH 2.2 only)

Include "sheet_bulge_common.pro";
SetFactory("OpenCASCADE");

// half-disks (x = r >= 0): shell region out to Inf_R, air inside Air_R
Disk(1) = {0, 0, 0, Inf_R};
Disk(2) = {0, 0, 0, Air_R};
Rectangle(3) = {0, -2*Inf_R, 0, 2*Inf_R, 4*Inf_R};
BooleanIntersection(4) = { Surface{1}; Delete; }{ Surface{3}; };
BooleanIntersection(5) = { Surface{2}; Delete; }{ Surface{3}; Delete; };

// turns and sheet
For k In {0:NbTurns-1}
  Rectangle(10 + k) = {Coil_Rin + k*(Turn_W + Turn_Gap), -Turn_H, 0, Turn_W, Turn_H};
EndFor
Rectangle(9) = {0, Coil_Gap, 0, Sheet_R, Sheet_T};

BooleanFragments{ Surface{4}; Delete; }{ Surface{5, 9, 10:10+NbTurns-1}; Delete; }

eps = 1e-5; // OpenCASCADE bounding boxes carry its tolerance
coil() = Surface In BoundingBox{Coil_Rin - eps, -Turn_H - eps, -1, Coil_Rin + NbTurns*(Turn_W + Turn_Gap) + eps, eps, 1};
sheet() = Surface In BoundingBox{-eps, Coil_Gap - eps, -1, Sheet_R + eps, Coil_Gap + Sheet_T + eps, 1};
inside() = Surface In BoundingBox{-eps, -Air_R - eps, -1, Air_R + eps, Air_R + eps, 1};
all() = Surface{:};
air() = inside();
air() -= {coil(), sheet()};
inf() = all();
inf() -= {inside()};

axis() = Curve In BoundingBox{-eps, -Inf_R - eps, -1, eps, Inf_R + eps, 1};
bnd() = CombinedBoundary{ Surface{all()}; };
outer() = {};
For i In {0:#bnd()-1}
  c = Abs(bnd(i));
  isAxis = 0;
  For j In {0:#axis()-1}
    If (c == axis(j))
      isAxis = 1;
    EndIf
  EndFor
  If (!isAxis)
    outer() += c;
  EndIf
EndFor

Physical Surface("AIR", AIR) = {air()};
Physical Surface("INF", INF) = {inf()};
Physical Surface("COIL", COIL) = {coil()};
Physical Surface("SHEET", SHEET) = {sheet()};
Physical Curve("AXIS", AXIS) = {axis()};
Physical Curve("OUTER", OUTER) = {outer()};

// sizes: fine at the coil and sheet, coarse far away, Lc_Sheet inside the sheet
Field[1] = Distance;
Field[1].CurvesList = {Abs(Boundary{ Surface{coil(), sheet()}; })};
Field[1].NumPointsPerCurve = 200;
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = Lc_Coil;
Field[2].SizeMax = Lc_Air;
Field[2].DistMin = 0;
Field[2].DistMax = 0.5*Air_R;
Field[3] = Box;
Field[3].VIn = Lc_Sheet;
Field[3].VOut = 1e22;
Field[3].XMin = 0;
Field[3].XMax = Sheet_R;
Field[3].YMin = Coil_Gap;
Field[3].YMax = Coil_Gap + Sheet_T;
Field[4] = Min;
Field[4].FieldsList = {2, 3};
Background Field = 4;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromCurvature = 0;
Mesh.Algorithm = 6;
