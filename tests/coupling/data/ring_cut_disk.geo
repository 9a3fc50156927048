// A closed one-turn ring under an aluminium disk, no symmetry plane: the ring's current path is the cut
// surface "cut" (the half-plane y = 0, x > 0 inside the ring). Written by hand for the 3D geometry-file tests.
SetFactory("OpenCASCADE");
DefineConstant[ r0 = 0.020, r1 = 0.025, z0 = -0.005, z1 = -0.001, rd = 0.03, td = 0.001, R = 0.08, Rs = 0.1 ];
Cylinder(1) = {0, 0, z0, 0, 0, z1 - z0, r1};
Cylinder(2) = {0, 0, z0, 0, 0, z1 - z0, r0};
BooleanDifference(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
Cylinder(4) = {0, 0, 0, 0, 0, td, rd};
Sphere(5) = {0, 0, 0, R};
Sphere(6) = {0, 0, 0, Rs};
Rectangle(20) = {r0, z0, 0, r1 - r0, z1 - z0};
Rotate {{1, 0, 0}, {0, 0, 0}, Pi/2} { Surface{20}; }
BooleanFragments{ Volume{6}; Volume{5}; Delete; }{ Volume{3, 4}; Surface{20}; Delete; }
e = 1e-6;
Physical Volume("ring") = Volume In BoundingBox{-r1 - e, -r1 - e, z0 - e, r1 + e, r1 + e, z1 + e};
Physical Volume("disk") = Volume In BoundingBox{-rd - e, -rd - e, -e, rd + e, rd + e, td + e};
inner() = Volume In BoundingBox{-R - e, -R - e, -R - e, R + e, R + e, R + e};
ring() = Volume In BoundingBox{-r1 - e, -r1 - e, z0 - e, r1 + e, r1 + e, z1 + e};
disk() = Volume In BoundingBox{-rd - e, -rd - e, -e, rd + e, rd + e, td + e};
air() = {};
For i In {0:#inner()-1}
  If (inner(i) != ring(0) && inner(i) != disk(0))
    air() += inner(i);
  EndIf
EndFor
Physical Volume("air") = air();
all() = Volume{:};
shell() = {};
For i In {0:#all()-1}
  If (all(i) != ring(0) && all(i) != disk(0))
    found = 0;
    For j In {0:#air()-1}
      If (all(i) == air(j))
        found = 1;
      EndIf
    EndFor
    If (!found)
      shell() += all(i);
    EndIf
  EndIf
EndFor
Physical Volume("shell") = shell();
Physical Surface("cut") = Surface In BoundingBox{r0 - e, -e, z0 - e, r1 + e, e, z1 + e};
MeshSize{ PointsOf{ Volume{:}; } } = 0.03;
