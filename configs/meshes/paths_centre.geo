// Centre crack for the kink-angle runs (issue 34, must-show 2; flem paths; docs/paths.md):
// the square [-L, L]^2 with a straight horizontal crack of half-length a = 1 through the centre
// (y = 0, -a <= x <= a), embedded in the surface and pre-cut by the scene. The crack is
// horizontal on every mesh kind (a structured grid needs it on a grid line): the scenes rotate
// the uniaxial load instead (configs/paths/centre_*.toml). Element size h within R of each tip,
// 2.5 h along the crack, growing to hmax at 6 a; quads when quads = 1 (gmsh's recombination).
// Physical groups: curves top, bottom, left, right, crack; points pin (bottom-left corner),
// roller (bottom-right corner); surface plate.
// Regenerate with: python3 tools/gen_meshes.py paths (gmsh 4.15.2)
h = 0.1;
quads = 0;
R = 0.8;
hmax = 1.5;
a = 1.0;
L = 10.0;
Point(1) = {-L, -L, 0, hmax};
Point(2) = {L, -L, 0, hmax};
Point(3) = {L, L, 0, hmax};
Point(4) = {-L, L, 0, hmax};
Point(5) = {-a, 0, 0, h};
Point(6) = {a, 0, 0, h};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Line(5) = {5, 6};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Curve{5} In Surface{1};
Field[1] = Distance;
Field[1].PointsList = {5, 6};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = h;
Field[2].SizeMax = hmax;
Field[2].DistMin = R;
Field[2].DistMax = 6 * a;
Field[3] = Distance;
Field[3].CurvesList = {5};
Field[3].Sampling = 200;
Field[4] = Threshold;
Field[4].InField = 3;
Field[4].SizeMin = 2.5 * h;
Field[4].SizeMax = hmax;
Field[4].DistMin = 0.1 * a;
Field[4].DistMax = 6 * a;
Field[5] = Min;
Field[5].FieldsList = {2, 4};
Background Field = 5;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
If (quads == 1)
  Recombine Surface{1};
  Mesh.Algorithm = 8;
  Mesh.RecombinationAlgorithm = 1;
EndIf
Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left") = {4};
Physical Curve("crack") = {5};
Physical Point("pin") = {1};
Physical Point("roller") = {2};
Physical Surface("plate") = {1};
