// Single-edge-notched unit square for the shear test (issue 34: the table's first row, must-show
// 2 and 3; flem paths; docs/paths.md): [0, 1]^2 with a slit from the middle of the left edge
// (0, 0.5) to the centre (0.5, 0.5), embedded and pre-cut by the scene; uniform element size h;
// quads when quads = 1 (gmsh's recombination), unstructured quads when quads = 2.
// Physical groups: curves bottom, right, top, left (both halves), crack; surface plate.
// Regenerate with: python3 tools/gen_meshes.py paths (gmsh 4.15.2)
h = 0.05;
quads = 0;
Point(1) = {0, 0, 0, h};
Point(2) = {1, 0, 0, h};
Point(3) = {1, 1, 0, h};
Point(4) = {0, 1, 0, h};
Point(5) = {0, 0.5, 0, h};
Point(6) = {0.5, 0.5, 0, h};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 5};
Line(5) = {5, 1};
Line(6) = {5, 6};
Curve Loop(1) = {1, 2, 3, 4, 5};
Plane Surface(1) = {1};
Curve{6} In Surface{1};
If (quads == 1)
  Recombine Surface{1};
  Mesh.Algorithm = 8;
  Mesh.RecombinationAlgorithm = 1;
EndIf
// quads = 2 (session 34, the shear test's `uquad` meshes): unstructured quads. Algorithm 8 above
// gives a regular grid on this square of uniform size at most sizes; Frontal-Delaunay
// triangles recombined by Blossom do not.
If (quads == 2)
  Recombine Surface{1};
  Mesh.Algorithm = 6;
  Mesh.RecombinationAlgorithm = 1;
EndIf
Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left") = {4, 5};
Physical Curve("crack") = {6};
Physical Surface("plate") = {1};
