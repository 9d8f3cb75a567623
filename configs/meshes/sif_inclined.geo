// Inclined centre crack in a square plate (issue 34, flem sif; docs/paths.md):
// the square [-L, L]^2 (L = 10 a: the plate is 20 a wide) with a straight crack of half-length
// a = 1 through the centre at angle beta to the loading axis y (the crack line makes phi =
// 90 - beta deg with +x, counter-clockwise). The crack is a line embedded in the surface; the
// scene pre-cuts it ([model] separated = ["crack"]), which splits its inner nodes and leaves the
// two end nodes (the tips) joined. Element size hmin near the tips, growing to hmax; quads when
// quads = 1 (gmsh's recombination; a few triangles may remain, FLEM takes mixed meshes).
// Physical groups: curves top, bottom, left, right, crack; points pin (bottom-left corner),
// roller (bottom-right corner); surface plate.
// Regenerate with: python3 tools/gen_meshes.py sif (gmsh 4.15.2)
beta = 45;
hmin = 0.04;
hmax = 1.5;
quads = 0;
a = 1.0;
L = 10.0;
phi = (90 - beta) * Pi / 180;
Point(1) = {-L, -L, 0, hmax};
Point(2) = {L, -L, 0, hmax};
Point(3) = {L, L, 0, hmax};
Point(4) = {-L, L, 0, hmax};
Point(5) = {-a * Cos(phi), -a * Sin(phi), 0, hmin};
Point(6) = {a * Cos(phi), a * Sin(phi), 0, hmin};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Line(5) = {5, 6};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Curve{5} In Surface{1};
// Refinement: hmin within 0.25 a of a tip, 2.5 hmin along the crack, up to hmax at 6 a.
Field[1] = Distance;
Field[1].PointsList = {5, 6};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = hmin;
Field[2].SizeMax = hmax;
Field[2].DistMin = 0.25 * a;
Field[2].DistMax = 6 * a;
Field[3] = Distance;
Field[3].CurvesList = {5};
Field[3].Sampling = 200;
Field[4] = Threshold;
Field[4].InField = 3;
Field[4].SizeMin = 2.5 * hmin;
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
