// The paper's direct shear model (figure 7), rebuilt: 21 quads + 1 triangle (n = 1).
// Units cm. Lower block [0,12] x [0,4] (held at its base); upper block on the shear plane
// y = 4 over x in [2,12], up to y = 8, with an inclined loaded side ab from b = (2,4) to
// a = (4,8) (the paper's p acts perpendicular to the initial side ab, split into X and Y).
// The triangle fills the top of the inclined column. bc = (2,4)-(4,4) is pre-separated;
// cd = (4,4)-(12,4) is the shear plane.
// n: refinement (each structured cell into n x n). Regenerate both meshes with
//   /work/venv-mesh/bin/python configs/paper/gen_meshes.py  (gmsh 4.15 Python package)
DefineConstant[ n = 1 ];
Point(1) = {0, 0, 0};    Point(2) = {12, 0, 0};
Point(3) = {12, 4, 0};   Point(4) = {4, 4, 0};   // d, c
Point(5) = {2, 4, 0};    Point(6) = {0, 4, 0};   // b
Point(7) = {12, 8, 0};   Point(8) = {4, 8, 0};   // a = 8
Point(9) = {3, 6, 0};    Point(10) = {4, 6, 0};
Point(11) = {12, 2, 0};  Point(12) = {0, 2, 0};  // the lower box holds y <= 2
// lower block
Line(1) = {1, 2}; Line(2) = {2, 11}; Line(14) = {11, 3}; Line(15) = {11, 12}; Line(16) = {12, 1}; Line(17) = {6, 12}; Line(3) = {3, 4}; Line(4) = {4, 5}; Line(5) = {5, 6};
// upper block
Line(7) = {3, 7}; Line(8) = {7, 8}; Line(9) = {8, 10}; Line(10) = {10, 4};
Line(11) = {5, 9}; Line(12) = {9, 10}; Line(13) = {9, 8};
Curve Loop(1) = {1, 2, 15, 16};
Plane Surface(1) = {1};
Curve Loop(5) = {-15, 14, 3, 4, 5, 17};
Plane Surface(5) = {5};
Curve Loop(2) = {-3, 7, 8, 9, 10};
Plane Surface(2) = {2};
Curve Loop(3) = {-4, -10, -12, -11};
Plane Surface(3) = {3};
Curve Loop(4) = {12, -9, -13};
Plane Surface(4) = {4};
Transfinite Curve{1, 15} = 6 * n + 1;
Transfinite Curve{7} = 2 * n + 1;
Transfinite Curve{2, 14, 16, 17} = n + 1;
Transfinite Curve{3, 8} = 4 * n + 1;
Transfinite Curve{4, 5, 9, 10, 11, 12, 13} = n + 1;
Transfinite Surface{1} = {1, 2, 11, 12};
Transfinite Surface{5} = {12, 11, 3, 6};
Transfinite Surface{2} = {4, 3, 7, 8};
Transfinite Surface{3} = {5, 4, 10, 9};
Recombine Surface{1, 2, 3, 5};
Physical Curve("bottom") = {1};
Physical Curve("box") = {1, 2, 15, 16};   // the lower box: its row y in [0, 2] is held
Physical Curve("lower_left") = {17};
Physical Curve("lower_right") = {14};
Physical Curve("lower_top") = {5};
Physical Curve("cd") = {3};
Physical Curve("bc") = {4};
Physical Curve("ab") = {11, 13};
Physical Curve("top") = {8};
Physical Curve("upper_right") = {7};
Physical Surface("box") = {1};
Physical Surface("lower") = {5};
Physical Surface("upper") = {2, 3, 4};
