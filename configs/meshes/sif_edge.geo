// Edge crack in a strip under uniform end tension (issue 34, flem sif; docs/paths.md):
// the strip [0, W] x [-H, H] (W = 1, H = 1.5 W) with a straight crack of depth a from the left
// edge at mid-height, (0, 0) - (a, 0). The crack is a line embedded in the surface; the scene
// pre-cuts it ([model] separated = ["crack"]): the mouth opens on the left edge, the tip (a, 0)
// stays joined. Element size hmin near the tip, growing to hmax; quads when quads = 1 (gmsh's
// recombination). Physical groups: curves top, bottom, left_low, left_up, right, crack;
// points pin (bottom-left corner), roller (bottom-right corner); surface strip.
// Regenerate with: python3 tools/gen_meshes.py sif (gmsh 4.15.2)
aw = 0.3;
hmin = 0.008;
hmax = 0.06;
quads = 0;
W = 1.0;
H = 1.5;
a = aw * W;
Point(1) = {0, -H, 0, hmax};
Point(2) = {W, -H, 0, hmax};
Point(3) = {W, H, 0, hmax};
Point(4) = {0, H, 0, hmax};
Point(5) = {0, 0, 0, hmin};
Point(6) = {a, 0, 0, hmin};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 5};
Line(5) = {5, 1};
Line(6) = {5, 6};
Curve Loop(1) = {1, 2, 3, 4, 5};
Plane Surface(1) = {1};
Curve{6} In Surface{1};
// Refinement: hmin within 0.05 W of the tip, 2.5 hmin along the crack, up to hmax at 0.6 W.
Field[1] = Distance;
Field[1].PointsList = {6};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = hmin;
Field[2].SizeMax = hmax;
Field[2].DistMin = 0.05 * W;
Field[2].DistMax = 0.6 * W;
Field[3] = Distance;
Field[3].CurvesList = {6};
Field[3].Sampling = 200;
Field[4] = Threshold;
Field[4].InField = 3;
Field[4].SizeMin = 2.5 * hmin;
Field[4].SizeMax = hmax;
Field[4].DistMin = 0.02 * W;
Field[4].DistMax = 0.6 * W;
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
Physical Curve("left_up") = {4};
Physical Curve("left_low") = {5};
Physical Curve("crack") = {6};
Physical Point("pin") = {1};
Physical Point("roller") = {2};
Physical Surface("strip") = {1};
