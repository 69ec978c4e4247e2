// The meridian of a cylinder R in [0, 2], Z in [0, 1] (mm; x = R, y = Z) for the axisymmetric Gmsh
// reader (src/mesh/gmsh.rs): curves `axis` (x = 0), `bottom`, `top`, `outer`, the surface `film`
// and the point `corner` (2, 0). Triangles by default; quadrilaterals (4 x 2, transfinite) with
// `-setnumber quad 1`; quad8 with `-order 2 -setnumber incomplete 1`. For example:
//   gmsh -2 meridian.geo -setnumber quad 1 -order 2 -format msh41 -o meridian-quad9-msh41.msh
//   gmsh -2 meridian.geo -order 2 -format msh22 -o meridian-tri6-msh22.msh
//   gmsh -2 meridian.geo -format msh41 -bin -o meridian-tri3-msh41-bin.msh
DefineConstant[ quad = 0, incomplete = 0 ];
Mesh.SecondOrderIncomplete = incomplete;
Point(1) = {0, 0, 0, 0.6};
Point(2) = {2, 0, 0, 0.6};
Point(3) = {2, 1, 0, 0.6};
Point(4) = {0, 1, 0, 0.6};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
If (quad)
  Transfinite Curve{1, 3} = 5;
  Transfinite Curve{2, 4} = 3;
  Transfinite Surface{1};
  Recombine Surface{1};
EndIf
Physical Curve("axis") = {4};
Physical Curve("bottom") = {1};
Physical Curve("top") = {3};
Physical Curve("outer") = {2};
Physical Surface("film") = {1};
Physical Point("corner") = {2};
