// Kalthoff-Winkler impact plate, half model (issue 36; docs/dynamic.md): the square
// [0, 0.1] x [0, 0.1] m, symmetry on y = 0, a notch from (0, 0.025) to (0.05, 0.025) embedded as
// a line that the scene pre-cuts ([model] separated = ["notch"]). The impactor acts on the left
// edge below the notch (curve "impact", 0 <= y <= 0.025). Triangles of size h in the band where
// the crack runs (x in [0.045, 0.09], y in [0.02, 0.1]: from the notch tip at 60 to 72 deg),
// 2 h elsewhere. Physical groups: curves bottom, right, top, left_up, impact, notch; surface plate.
// Regenerate with: python3 tools/gen_meshes.py dynamic (gmsh 4.15.2)
h = 0.001;
Point(1) = {0, 0, 0, 2 * h};
Point(2) = {0.1, 0, 0, 2 * h};
Point(3) = {0.1, 0.1, 0, 2 * h};
Point(4) = {0, 0.1, 0, 2 * h};
Point(5) = {0, 0.025, 0, h};
Point(6) = {0.05, 0.025, 0, h};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 5};
Line(5) = {5, 1};
Line(6) = {5, 6};
Curve Loop(1) = {1, 2, 3, 4, 5};
Plane Surface(1) = {1};
Curve{6} In Surface{1};
Field[1] = Box;
Field[1].VIn = h;
Field[1].VOut = 2 * h;
Field[1].XMin = 0.045;
Field[1].XMax = 0.09;
Field[1].YMin = 0.02;
Field[1].YMax = 0.1;
Field[1].Thickness = 0.005;
Background Field = 1;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left_up") = {4};
Physical Curve("impact") = {5};
Physical Curve("notch") = {6};
Physical Surface("plate") = {1};
