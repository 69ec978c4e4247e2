// The multilayer stack of the `stack` example, drawn in mm (read it with `mesh.scale = 1e-3`):
// a quarter (x, y ≥ 0) of a 4 x 4 mm stack of N = 4 films of 50 µm, electrodes on every interface
// and on the top and bottom faces, stopping 0.4 mm short of the sides (the passive border).
// Physical groups carry the set names of the `stack` generator: volumes `active` (under the
// electrodes) and `border`, surfaces `electrode_0` … `electrode_4` (the electroded part of each
// interface; the inner ones are internal surfaces), `high_voltage` (electrodes 1, 3), `ground`
// (0, 2, 4), `bottom`, `top`, `side` (x = 2 and y = 2 mm), `symmetry_x`, `symmetry_y`. A scenario
// `stack.toml` runs on it with `mesh.file = "stack.msh"` and `mesh.scale = 1e-3` in place of the
// generator keys (the sets keep their names); a mesh read from a file is not known to be a quarter,
// so charge, capacitance, reactions and energies are then those of the meshed quarter (× 4 for the
// device).
// Tetrahedra refined toward the electrode edges (a distance field on the edge lines):
//   gmsh -3 stack.geo -format msh41 -o stack.msh            (tet4; tet10: add `-order 2`)
//   gmsh -3 stack.geo -setnumber lc_edge 0.01 -o stack.msh  (finer at the edges, mm)
SetFactory("OpenCASCADE");
DefineConstant[ N = 4, t = 0.05, half = 2, border = 0.4, lc = 0.25, lc_edge = 0.025 ];
e = half - border;          // electrode edge
H = N * t;

// per film: the active block and the two blocks of the border (x > e, and y > e with x < e)
For k In {0:N-1}
  Box(newv) = {0, 0, k * t, e, e, t};
  Box(newv) = {e, 0, k * t, border, half, t};
  Box(newv) = {0, e, k * t, e, border, t};
EndFor
Coherence;  // fuse coincident faces: one conforming volume mesh with internal surfaces

eps = 1e-4;
Physical Volume("active") = Volume In BoundingBox{-eps, -eps, -eps, e + eps, e + eps, H + eps};
b() = Volume In BoundingBox{e - eps, -eps, -eps, half + eps, half + eps, H + eps};
b() += Volume In BoundingBox{-eps, e - eps, -eps, e + eps, half + eps, H + eps};
Physical Volume("border") = b();
hv() = {};
gnd() = {};
For k In {0:N}
  s() = Surface In BoundingBox{-eps, -eps, k * t - eps, e + eps, e + eps, k * t + eps};
  Physical Surface(Sprintf("electrode_%g", k)) = s();
  If (k % 2 == 1)
    hv() += s();
  Else
    gnd() += s();
  EndIf
EndFor
Physical Surface("high_voltage") = hv();
Physical Surface("ground") = gnd();
Physical Surface("bottom") = Surface In BoundingBox{-eps, -eps, -eps, half + eps, half + eps, eps};
Physical Surface("top") = Surface In BoundingBox{-eps, -eps, H - eps, half + eps, half + eps, H + eps};
sd() = Surface In BoundingBox{half - eps, -eps, -eps, half + eps, half + eps, H + eps};
sd() += Surface In BoundingBox{-eps, half - eps, -eps, half + eps, half + eps, H + eps};
Physical Surface("side") = sd();
Physical Surface("symmetry_x") = Surface In BoundingBox{-eps, -eps, -eps, eps, half + eps, H + eps};
Physical Surface("symmetry_y") = Surface In BoundingBox{-eps, -eps, -eps, half + eps, eps, H + eps};

// mesh size: lc far away, lc_edge at the electrode edge lines (x = e or y = e on z = k t)
edges() = {};
For k In {0:N}
  edges() += Curve In BoundingBox{e - eps, -eps, k * t - eps, e + eps, e + eps, k * t + eps};
  edges() += Curve In BoundingBox{-eps, e - eps, k * t - eps, e + eps, e + eps, k * t + eps};
EndFor
Field[1] = Distance;
Field[1].CurvesList = {edges()};
Field[1].Sampling = 200;
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = lc_edge;
Field[2].SizeMax = lc;
Field[2].DistMin = 2 * t;
Field[2].DistMax = 0.8;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
