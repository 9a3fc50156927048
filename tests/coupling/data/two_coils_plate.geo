// Two half-ring coils under an aluminium plate, a copper slug above it: a 3D geometry written by hand the
// way a user writes one (no pulseform builder), for the 3D geometry-file tests. Half model y >= 0: the
// plane y = 0 is a symmetry plane (the coils' currents cross it at right angles). Lengths in m.
SetFactory("OpenCASCADE");
DefineConstant[
  xc = 0.015,      // |x| of the coils' axes
  r0 = 0.006,      // inner radius of the rings
  r1 = 0.010,      // outer radius
  hc = 0.003,      // coil height
  gap = 0.001,     // coil top to plate
  tp = 0.002,      // plate thickness
  R = 0.05,        // air sphere
  Rs = 0.06        // shell
];
// the coils: half rings y >= 0 (angle 0..Pi from +x), their end faces on y = 0 are the terminals
Cylinder(1) = {-xc, 0, -gap - hc, 0, 0, hc, r1, Pi};
Cylinder(2) = {-xc, 0, -gap - hc, 0, 0, hc, r0, Pi};
BooleanDifference(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
Cylinder(4) = {xc, 0, -gap - hc, 0, 0, hc, r1, Pi};
Cylinder(5) = {xc, 0, -gap - hc, 0, 0, hc, r0, Pi};
BooleanDifference(6) = { Volume{4}; Delete; }{ Volume{5}; Delete; };
Box(7) = {-0.03, 0, 0, 0.06, 0.015, tp};            // the plate
Box(8) = {-0.005, 0, tp + 0.002, 0.01, 0.005, 0.002}; // the slug, 2 mm above the plate
Sphere(9) = {0, 0, 0, R, -Pi/2, Pi/2, Pi};
Sphere(10) = {0, 0, 0, Rs, -Pi/2, Pi/2, Pi};
BooleanFragments{ Volume{10}; Volume{9}; Delete; }{ Volume{3, 6, 7, 8}; Delete; }

e = 1e-6;
coil_a() = Volume In BoundingBox{-xc - r1 - e, -e, -gap - hc - e, -xc + r1 + e, r1 + e, -gap + e};
coil_b() = Volume In BoundingBox{xc - r1 - e, -e, -gap - hc - e, xc + r1 + e, r1 + e, -gap + e};
plate() = Volume In BoundingBox{-0.03 - e, -e, -e, 0.03 + e, 0.015 + e, tp + e};
slug() = Volume In BoundingBox{-0.005 - e, -e, tp + 0.002 - e, 0.005 + e, 0.005 + e, tp + 0.004 + e};
inner() = Volume In BoundingBox{-R - e, -e, -R - e, R + e, R + e, R + e};
air() = {};
For i In {0:#inner()-1}
  If (inner(i) != coil_a(0) && inner(i) != coil_b(0) && inner(i) != plate(0) && inner(i) != slug(0))
    air() += inner(i);
  EndIf
EndFor
all() = Volume{:};
shell() = {};
For i In {0:#all()-1}
  If (all(i) != coil_a(0) && all(i) != coil_b(0) && all(i) != plate(0) && all(i) != slug(0))
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
Physical Volume("coil_a") = coil_a();
Physical Volume("coil_b") = coil_b();
Physical Volume("plate") = plate();
Physical Volume("slug") = slug();
Physical Volume("air") = air();
Physical Volume("shell") = shell();
// terminals: the faces on y = 0 at angle 0 (x > axis: in) and angle Pi (x < axis: out)
Physical Surface("a_in") = Surface In BoundingBox{-xc + r0 - e, -e, -gap - hc - e, -xc + r1 + e, e, -gap + e};
Physical Surface("a_out") = Surface In BoundingBox{-xc - r1 - e, -e, -gap - hc - e, -xc - r0 + e, e, -gap + e};
Physical Surface("b_in") = Surface In BoundingBox{xc + r0 - e, -e, -gap - hc - e, xc + r1 + e, e, -gap + e};
Physical Surface("b_out") = Surface In BoundingBox{xc - r1 - e, -e, -gap - hc - e, xc - r0 + e, e, -gap + e};
// the plate's ends (held in the tests)
Physical Surface("plate_ends") = Surface In BoundingBox{-0.03 - e, -e, -e, -0.03 + e, 0.015 + e, tp + e};
Physical Surface("plate_ends") += Surface In BoundingBox{0.03 - e, -e, -e, 0.03 + e, 0.015 + e, tp + e};

MeshSize{ PointsOf{ Volume{:}; } } = 0.02;
Mesh.MeshSizeMax = 0.02;
