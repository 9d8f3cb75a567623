// Dynamic crack branching plate (issue 36; docs/dynamic.md): [0, 0.1] x [0, 0.04] m with a
// notch from (0, 0.02) to (0.05, 0.02) embedded as a line that the scene pre-cuts
// ([model] separated = ["notch"]); traction on top and bottom. Triangles of size h in the band
// where the crack runs and branches (x in [0.045, 0.1], y in [0.008, 0.032]), 2 h elsewhere.
// Physical groups: curves bottom, right, top, left_up, left_low, notch; surface plate.
// Regenerate with: python3 tools/gen_meshes.py dynamic (gmsh 4.15.2)
h = 0.0005;
Point(1) = {0, 0, 0, 2 * h};
Point(2) = {0.1, 0, 0, 2 * h};
Point(3) = {0.1, 0.04, 0, 2 * h};
Point(4) = {0, 0.04, 0, 2 * h};
Point(5) = {0, 0.02, 0, h};
Point(6) = {0.05, 0.02, 0, h};
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
Field[1].XMax = 0.1;
Field[1].YMin = 0.008;
Field[1].YMax = 0.032;
Field[1].Thickness = 0.003;
Background Field = 1;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left_up") = {4};
Physical Curve("left_low") = {5};
Physical Curve("notch") = {6};
Physical Surface("plate") = {1};
