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

// the die (Die = 1): block minus the cavity, the cavity edge rounded with Die_Re (a true arc)
zf = Coil_Gap + Sheet_T + Die_Gap; // the die's lower face
tools() = {5, 9, 10:10+NbTurns-1};
If (Die)
  Point(101) = {Die_Rc + Die_Re, zf, 0};
  Point(102) = {Die_Ro, zf, 0};
  Point(103) = {Die_Ro, zf + Die_H, 0};
  Point(104) = {0, zf + Die_H, 0};
  Point(105) = {0, zf + Die_D, 0};
  Point(106) = {Die_Rc, zf + Die_D, 0};
  Point(107) = {Die_Rc, zf + Die_Re, 0};
  Point(108) = {Die_Rc + Die_Re, zf + Die_Re, 0}; // centre of the fillet
  Line(101) = {101, 102}; Line(102) = {102, 103}; Line(103) = {103, 104};
  Line(104) = {104, 105}; Line(105) = {105, 106}; Line(106) = {106, 107};
  Circle(107) = {107, 108, 101};
  Curve Loop(101) = {101:107};
  Plane Surface(8) = {101};
  tools() += 8;
EndIf

BooleanFragments{ Surface{4}; Delete; }{ Surface{tools()}; Delete; }

eps = 1e-5; // OpenCASCADE bounding boxes carry its tolerance
coil() = Surface In BoundingBox{Coil_Rin - eps, -Turn_H - eps, -1, Coil_Rin + NbTurns*(Turn_W + Turn_Gap) + eps, eps, 1};
sheet() = Surface In BoundingBox{-eps, Coil_Gap - eps, -1, Sheet_R + eps, Coil_Gap + Sheet_T + eps, 1};
inside() = Surface In BoundingBox{-eps, -Air_R - eps, -1, Air_R + eps, Air_R + eps, 1};
all() = Surface{:};
die() = {};
If (Die) // the cavity's air is open towards the sheet, so it is not inside this box
  die() = Surface In BoundingBox{-eps, zf - eps, -1, Die_Ro + eps, zf + Die_H + eps, 1};
EndIf
air() = inside();
air() -= {coil(), sheet(), die()};
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
If (Coil_Split > 0) // two coils: the first Coil_Split turns from the axis, and the others
  inner() = Surface In BoundingBox{Coil_Rin - eps, -Turn_H - eps, -1,
                                   Coil_Rin + Coil_Split*(Turn_W + Turn_Gap) - Turn_Gap + eps, eps, 1};
  outer_turns() = coil();
  outer_turns() -= {inner()};
  Physical Surface("COIL_INNER", COIL_INNER) = {inner()};
  Physical Surface("COIL_OUTER", COIL_OUTER) = {outer_turns()};
Else
  Physical Surface("COIL", COIL) = {coil()};
EndIf
Physical Surface("SHEET", SHEET) = {sheet()};
If (Die)
  Physical Surface("DIE", DIE) = {die()};
EndIf
Physical Curve("AXIS", AXIS) = {axis()};
Physical Curve("OUTER", OUTER) = {outer()};

// sizes: fine at the coil and sheet, coarse far away, Lc_Sheet inside the sheet
Field[1] = Distance;
Field[1].CurvesList = {Abs(Boundary{ Surface{coil(), sheet(), die()}; })};
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
Field[5] = Box; // Lc_Die inside the die's box (used when Die = 1)
Field[5].VIn = Die ? Lc_Die : 1e22;
Field[5].VOut = 1e22;
Field[5].XMin = 0;
Field[5].XMax = Die_Ro;
Field[5].YMin = zf;
Field[5].YMax = zf + Die_H;
Field[4] = Min;
Field[4].FieldsList = {2, 3, 5};
Background Field = 4;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromCurvature = 0;
Mesh.Algorithm = 6;
