// The film of the `film` example (docs/theory.md): a quarter 10 x 10 x 1 mm, drawn in mm
// (read it with `mesh.scale = 1e-3`). Physical groups carry the set names of the `box` generator:
// volume `elastomer`, faces x0 x1 y0 y1 z0 z1 (low/high end of each axis), and `bottom`/`top` as
// aliases of z0/z1.
//
// The test meshes under tests/data/gmsh/ were written by Gmsh 4.15 with:
//   gmsh -3 film.geo -format msh41 -bin 0 -o film-tet4-msh41.msh
//   gmsh -3 film.geo -format msh41 -bin 1 -o film-tet4-msh41-bin.msh
//   gmsh -3 film.geo -format msh22        -o film-tet4-msh22.msh
//   (tet10: add `-order 2`; hex8: add `-setnumber hex 1`)
// A finer mesh: `-setnumber lc 1` (element size in mm).
SetFactory("OpenCASCADE");
DefineConstant[ hex = 0, lc = 5 ];

Box(1) = {0, 0, 0, 10, 10, 1};
MeshSize{ PointsOf{ Volume{1}; } } = lc;

If (hex)
  // a structured 3 x 3 x 2 grid of hexahedra
  Transfinite Curve{:} = 4;
  For i In {0:1}
    For j In {0:1}
      Transfinite Curve{ Curve In BoundingBox{10*i - 0.1, 10*j - 0.1, -0.1,
                                              10*i + 0.1, 10*j + 0.1, 1.1} } = 3;
    EndFor
  EndFor
  Transfinite Surface{:};
  Recombine Surface{:};
  Transfinite Volume{1};
EndIf

eps = 1e-3;
Physical Volume("elastomer") = {1};
Physical Surface("x0") = Surface In BoundingBox{-eps, -eps, -eps, eps, 10 + eps, 1 + eps};
Physical Surface("x1") = Surface In BoundingBox{10 - eps, -eps, -eps, 10 + eps, 10 + eps, 1 + eps};
Physical Surface("y0") = Surface In BoundingBox{-eps, -eps, -eps, 10 + eps, eps, 1 + eps};
Physical Surface("y1") = Surface In BoundingBox{-eps, 10 - eps, -eps, 10 + eps, 10 + eps, 1 + eps};
Physical Surface("z0") = Surface In BoundingBox{-eps, -eps, -eps, 10 + eps, 10 + eps, eps};
Physical Surface("z1") = Surface In BoundingBox{-eps, -eps, 1 - eps, 10 + eps, 10 + eps, 1 + eps};
Physical Surface("bottom") = Surface In BoundingBox{-eps, -eps, -eps, 10 + eps, 10 + eps, eps};
Physical Surface("top") = Surface In BoundingBox{-eps, -eps, 1 - eps, 10 + eps, 10 + eps, 1 + eps};
