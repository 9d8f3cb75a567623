// Cook's membrane (Cook 1974; the tapered cantilever of e.g. Simo & Rifai 1990, fig. 6):
// the trapezoid (0, 0), (48, 44), (48, 60), (0, 44), structured n x n quadrilaterals
// (transfinite + recombine), n = 4 here; cook_8/cook_16 are written with n = 8 and 16 by
// tools/gen_meshes.py (it sets the transfinite counts through gmsh.model.mesh).
// Physical groups: lines clamp (x = 0), load (x = 48), bottom, top; point tip (48, 52), the
// middle of the loaded edge where the reference deflection 23.96 is quoted; surface membrane. Regenerate with: python3 tools/gen_meshes.py (gmsh 4.15 Python package).
n = 4;
Point(1) = {0, 0, 0, 1};
Point(2) = {48, 44, 0, 1};
Point(3) = {48, 60, 0, 1};
Point(4) = {0, 44, 0, 1};
Point(5) = {48, 52, 0, 1};
Line(1) = {1, 2};
Line(2) = {2, 5};
Line(5) = {5, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 5, 3, 4};
Plane Surface(1) = {1};
Transfinite Curve{1, 3, 4} = n + 1;
Transfinite Curve{2, 5} = n / 2 + 1;
Transfinite Surface{1} = {1, 2, 3, 4};
Recombine Surface{1};
Physical Curve("bottom") = {1};
Physical Curve("load") = {2, 5};
Physical Curve("top") = {3};
Physical Curve("clamp") = {4};
Physical Point("tip") = {5};
Physical Surface("membrane") = {1};
