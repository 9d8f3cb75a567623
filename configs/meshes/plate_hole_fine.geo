// Quarter of a plate with a circular hole: the square [0, 2] x [0, 2] minus the disc of
// radius 0.5 at the origin, unstructured triangles (713): plate_hole.geo at half the size.
// Physical groups: lines left (x = 0), bottom (y = 0), right (x = 2), top (y = 2), hole (the arc);
// surface plate. Regenerate with: python3 tools/gen_meshes.py
r = 0.5;
L = 2.0;
h = 0.15;
Point(1) = {0, 0, 0, h};
Point(2) = {r, 0, 0, h / 2};
Point(3) = {L, 0, 0, h};
Point(4) = {L, L, 0, h};
Point(5) = {0, L, 0, h};
Point(6) = {0, r, 0, h / 2};
Line(1) = {2, 3};
Line(2) = {3, 4};
Line(3) = {4, 5};
Line(4) = {5, 6};
Circle(5) = {6, 1, 2};
Curve Loop(1) = {1, 2, 3, 4, 5};
Plane Surface(1) = {1};
Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left") = {4};
Physical Curve("hole") = {5};
Physical Surface("plate") = {1};
