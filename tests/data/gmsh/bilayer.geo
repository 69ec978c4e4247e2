// Two 10 x 10 x 0.5 mm layers (mm units) sharing the internal surface `middle` (an embedded
// electrode); volumes `lower` and `upper`, faces x0 y0 bottom top. For tests/gmsh.rs:
//   gmsh -3 bilayer.geo -order 2 -format msh41 -o bilayer-tet10-msh41.msh
//   gmsh -3 bilayer.geo -format msh22 -o bilayer-tet4-msh22.msh
SetFactory("OpenCASCADE");
lc = 5;
Box(1) = {0, 0, 0, 10, 10, 0.5};
Box(2) = {0, 0, 0.5, 10, 10, 0.5};
BooleanFragments{ Volume{1}; Delete; }{ Volume{2}; Delete; }
MeshSize{ PointsOf{ Volume{:}; } } = lc;
eps = 1e-3;
Physical Volume("lower") = Volume In BoundingBox{-eps, -eps, -eps, 10 + eps, 10 + eps, 0.5 + eps};
Physical Volume("upper") = Volume In BoundingBox{-eps, -eps, 0.5 - eps, 10 + eps, 10 + eps, 1 + eps};
Physical Surface("x0") = Surface In BoundingBox{-eps, -eps, -eps, eps, 10 + eps, 1 + eps};
Physical Surface("y0") = Surface In BoundingBox{-eps, -eps, -eps, 10 + eps, eps, 1 + eps};
Physical Surface("bottom") = Surface In BoundingBox{-eps, -eps, -eps, 10 + eps, 10 + eps, eps};
Physical Surface("middle") = Surface In BoundingBox{-eps, -eps, 0.5 - eps, 10 + eps, 10 + eps, 0.5 + eps};
Physical Surface("top") = Surface In BoundingBox{-eps, -eps, 1 - eps, 10 + eps, 10 + eps, 1 + eps};
