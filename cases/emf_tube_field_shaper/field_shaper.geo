// Electromagnetic tube compression with a slotted field shaper: a quarter model (y >= 0, z >= 0; with
// z_symmetric = 0 the half y >= 0, both halves in z).
//
// Axis z. A solenoid (the coil: one homogenised winding block, azimuthal current) surrounds a copper field
// shaper: a thick ring whose outer face lies under the coil and whose bore is stepped down by a conical
// taper to a shorter inner face around the tube; one axial slit of width w_slit, centred on the plane
// y = 0 at +x, cuts through its wall. An aluminium tube lies in the bore. The model keeps y >= 0 and z >= 0:
// the plane z = 0 is the mid-plane of coil, shaper and tube; the plane y = 0 passes through the axis and the
// middle of the slit (so the model holds half of the slit: 0 <= y <= w_slit / 2 at x > 0).
// Air: a quarter ball of radius R_air; shell: the quarter layer R_air < r < R_shell (transformation to
// infinity).
//
// Physical groups (the case's role map): volumes "coil", "shaper", "tube", "air", "shell"; surfaces
// "tube_end" (the tube's free end at z = L_tube / 2, for users who hold it) and "shaper_slit" (the slit's
// face of the modelled half, for pictures).
// Every size and dimension is a DefineConstant (m): gmsh -setnumber NAME VALUE, or the case's
// geometry.parameters, changes it. Element sizes: mesh_size_air (outer sphere), mesh_size_shell; the case gives the
// conductors' sizes per volume (geometry.mesh_sizes); mesh_size_cond is this file's own default for them.
SetFactory("OpenCASCADE");

DefineConstant[
  R_tube_in = {18.5e-3, Name "Tube/inner radius"},
  t_tube = {1.5e-3, Name "Tube/wall thickness"},
  L_tube = {70e-3, Name "Tube/length"},
  gap_tube = {1.0e-3, Name "Shaper/radial gap bore - tube"},
  L_inner = {15e-3, Name "Shaper/length of the inner face"},
  L_outer = {40e-3, Name "Shaper/length of the outer face"},
  R_taper = {30e-3, Name "Shaper/radius where the taper reaches the outer length"},
  R_shaper = {40e-3, Name "Shaper/outer radius"},
  w_slit = {2e-3, Name "Shaper/slit width"},
  gap_coil = {2e-3, Name "Coil/radial gap shaper - coil (insulation)"},
  t_coil = {6e-3, Name "Coil/radial build of the winding"},
  L_coil = {36e-3, Name "Coil/length of the winding"},
  R_air = {0.12, Name "Air/radius"},
  R_shell = {0.15, Name "Air/shell outer radius"},
  mesh_size_air = {0.02, Name "Mesh/air size on the outer sphere"},
  mesh_size_shell = {0.03, Name "Mesh/shell size"},
  mesh_size_cond = {3e-3, Name "Mesh/default conductor size"},
  z_symmetric = {1, Choices{0, 1}, Name "Model/keep z >= 0 only (the mid-plane a symmetry plane)"}
];
// z_symmetric = 0 models both halves in z (y >= 0 only): a check of the mid-plane's symmetry condition; a
// case using it must drop its z = 0 [[symmetry]] entry (the runner refuses a plane the model does not end on)
zs = (z_symmetric == 0) ? 1 : 0;   // 1: the model extends below z = 0 as well

R_tube_out = R_tube_in + t_tube;
R_bore = R_tube_out + gap_tube;
R_coil = R_shaper + gap_coil;
If (R_taper <= R_bore || R_taper >= R_shaper || L_inner > L_outer || L_coil > L_outer + 2 * gap_coil ||
    w_slit <= 0 || R_shell <= R_air || R_air <= 1.5 * (R_coil + t_coil) || L_tube / 2 >= R_air)
  Error("field_shaper.geo: inconsistent dimensions (R_bore < R_taper < R_shaper, L_inner <= L_outer, air around the coil)");
  Abort;
EndIf

// meridian sections (the half-plane y = 0, x = r > 0, z >= 0), revolved by pi about z: the y >= 0 half

s_sec = news; Rectangle(s_sec) = {R_tube_in, -zs * L_tube / 2, 0, t_tube, (1 + zs) * L_tube / 2};
Rotate {{1, 0, 0}, {0, 0, 0}, Pi / 2} { Surface{s_sec}; }
s_rev[] = Extrude {{0, 0, 1}, {0, 0, 0}, Pi} { Surface{s_sec}; }; v_tube = s_rev[1];

s_sec = news; Rectangle(s_sec) = {R_coil, -zs * L_coil / 2, 0, t_coil, (1 + zs) * L_coil / 2};
Rotate {{1, 0, 0}, {0, 0, 0}, Pi / 2} { Surface{s_sec}; }
s_rev[] = Extrude {{0, 0, 1}, {0, 0, 0}, Pi} { Surface{s_sec}; }; v_coil = s_rev[1];

// the shaper's section: inner face r = R_bore for |z| <= L_inner / 2, a conical taper to (R_taper, L_outer / 2),
// the end face z = L_outer / 2 out to R_shaper, the outer face r = R_shaper under the coil
p1 = newp; Point(p1) = {R_bore, 0, -zs * L_inner / 2};
p2 = newp; Point(p2) = {R_shaper, 0, -zs * L_outer / 2};
p3 = newp; Point(p3) = {R_shaper, 0, L_outer / 2};
p4 = newp; Point(p4) = {R_taper, 0, L_outer / 2};
p5 = newp; Point(p5) = {R_bore, 0, L_inner / 2};
If (zs)
  p6 = newp; Point(p6) = {R_taper, 0, -L_outer / 2};
  l1 = newl; Line(l1) = {p1, p6};
  l0 = newl; Line(l0) = {p6, p2};
Else
  l1 = newl; Line(l1) = {p1, p2};
EndIf
l2 = newl; Line(l2) = {p2, p3};
l3 = newl; Line(l3) = {p3, p4};
l4 = newl; Line(l4) = {p4, p5};
l5 = newl; Line(l5) = {p5, p1};
If (zs)
  cl = newll; Curve Loop(cl) = {l1, l0, l2, l3, l4, l5};
Else
  cl = newll; Curve Loop(cl) = {l1, l2, l3, l4, l5};
EndIf
s_sec = news; Plane Surface(s_sec) = {cl};
s_rev[] = Extrude {{0, 0, 1}, {0, 0, 0}, Pi} { Surface{s_sec}; }; v_ring = s_rev[1];
// the slit: the wall cut through at |y| < w_slit / 2, x > 0 (its modelled half: 0 <= y <= w_slit / 2)
v_cut = newv; Box(v_cut) = {0, 0, -zs * L_outer, 2 * R_shaper, w_slit / 2, (1 + zs) * L_outer};
v_shaper() = BooleanDifference{ Volume{v_ring}; Delete; }{ Volume{v_cut}; Delete; };

// air and shell: quarter balls
v_big = newv; Sphere(v_big) = {0, 0, 0, R_shell};
v_q = newv; Box(v_q) = {-2 * R_shell, 0, -zs * 2 * R_shell, 4 * R_shell, 2 * R_shell, (1 + zs) * 2 * R_shell};
v_ball() = BooleanIntersection{ Volume{v_big}; Delete; }{ Volume{v_q}; Delete; };
v_small = newv; Sphere(v_small) = {0, 0, 0, R_air};
v_q = newv; Box(v_q) = {-2 * R_shell, 0, -zs * 2 * R_shell, 4 * R_shell, 2 * R_shell, (1 + zs) * 2 * R_shell};
v_in() = BooleanIntersection{ Volume{v_small}; Delete; }{ Volume{v_q}; Delete; };

// one conforming mesh: fragment everything (the inner ball is cut by the three conductors)
BooleanFragments{ Volume{v_ball(), v_in()}; Delete; }{ Volume{v_tube, v_coil, v_shaper()}; Delete; }

// identify the fragments by their bounding boxes (tags change in the fragmentation)
eps = 1e-6;
tube() = Volume In BoundingBox{-R_tube_out - eps, -eps, -zs * L_tube / 2 - eps, R_tube_out + eps, R_tube_out + eps, L_tube / 2 + eps};
shaper() = Volume In BoundingBox{-R_shaper - eps, -eps, -zs * L_outer / 2 - eps, R_shaper + eps, R_shaper + eps, L_outer / 2 + eps};
shaper() -= tube();
coil() = Volume In BoundingBox{-R_coil - t_coil - eps, -eps, -zs * L_coil / 2 - eps, R_coil + t_coil + eps, R_coil + t_coil + eps,
                               L_coil / 2 + eps};
coil() -= shaper();
coil() -= tube();
inner() = Volume In BoundingBox{-R_air - eps, -eps, -zs * R_air - eps, R_air + eps, R_air + eps, R_air + eps};
air() = inner();
air() -= tube();
air() -= shaper();
air() -= coil();
shell() = Volume{:};
shell() -= inner();
If (#tube() != 1 || #shaper() != 1 || #coil() != 1 || #air() != 1 || #shell() != 1)
  Error("field_shaper.geo: expected one volume each, got tube %g, shaper %g, coil %g, air %g, shell %g",
        #tube(), #shaper(), #coil(), #air(), #shell());
  Abort;
EndIf

Physical Volume("coil") = coil();
Physical Volume("shaper") = shaper();
Physical Volume("tube") = tube();
Physical Volume("air") = air();
Physical Volume("shell") = shell();
Physical Surface("tube_end") = Surface In BoundingBox{-R_tube_out - eps, -eps, L_tube / 2 - eps,
                                                      R_tube_out + eps, R_tube_out + eps, L_tube / 2 + eps};
Physical Surface("shaper_slit") = Surface In BoundingBox{-eps, w_slit / 2 - eps, -zs * L_outer / 2 - eps,
                                                         R_shaper + eps, w_slit / 2 + eps, L_outer / 2 + eps};

// element sizes: the conductors' own (the case's geometry.mesh_sizes override them per volume), the air's
// on the outer sphere, the shell's on its outer sphere
MeshSize{ PointsOf{ Volume{shell()}; } } = mesh_size_shell;
MeshSize{ PointsOf{ Volume{air()}; } } = mesh_size_air;
MeshSize{ PointsOf{ Volume{coil(), shaper(), tube()}; } } = mesh_size_cond;
Mesh.MeshSizeMax = mesh_size_shell;
Mesh.MeshSizeFromCurvature = 0;
