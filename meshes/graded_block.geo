// graded_block.geo -- quarter model of a block for a contact centred at the origin:
// [0, L] x [0, L] x [0, H], all-hexahedral (transfinite), 2 nd cells per direction,
// graded geometrically (each cell r times the previous one, away from the origin) so
// the smallest cells are at the corner (0, 0, 0) of the contact face z = 0.
//
// Parameters (gmsh -setnumber, or read_gmsh(..., parameters={...})):
//   nd   refinement: 2 nd cells along x, y and z (default 4)
//   r    ratio of neighbouring cell sizes (default 1.2; 1 = uniform)
//   L    side in x and y (default 4)       H   height (default 4)
//
// Physical surfaces:
//   "contact"  z = 0        "top"      z = H
//   "sym_x"    x = 0        "outer_x"  x = L
//   "sym_y"    y = 0        "outer_y"  y = L
// Physical volume "block".

DefineConstant[ nd = {4, Min 1, Max 64, Step 1, Name "nd"} ];
DefineConstant[ r = {1.2, Min 1, Max 3, Name "r"} ];
DefineConstant[ L = {4, Name "L"} ];
DefineConstant[ H = {4, Name "H"} ];

Point(1) = {0, 0, 0};  Point(2) = {L, 0, 0};  Point(3) = {L, L, 0};  Point(4) = {0, L, 0};
Point(5) = {0, 0, H};  Point(6) = {L, 0, H};  Point(7) = {L, L, H};  Point(8) = {0, L, H};

// every line runs away from the origin, so Progression r grows the cells outwards
Line(1) = {1, 2};  Line(2) = {4, 3};  Line(3) = {5, 6};  Line(4) = {8, 7};     // along x
Line(5) = {1, 4};  Line(6) = {2, 3};  Line(7) = {5, 8};  Line(8) = {6, 7};     // along y
Line(9) = {1, 5};  Line(10) = {2, 6}; Line(11) = {4, 8}; Line(12) = {3, 7};    // along z
Transfinite Curve{1:12} = 2 * nd + 1 Using Progression r;

Curve Loop(1) = {5, 2, -6, -1};    Plane Surface(1) = {1};    // z = 0
Curve Loop(2) = {3, 8, -4, -7};    Plane Surface(2) = {2};    // z = H
Curve Loop(3) = {9, 7, -11, -5};   Plane Surface(3) = {3};    // x = 0
Curve Loop(4) = {6, 12, -8, -10};  Plane Surface(4) = {4};    // x = L
Curve Loop(5) = {1, 10, -3, -9};   Plane Surface(5) = {5};    // y = 0
Curve Loop(6) = {11, 4, -12, -2};  Plane Surface(6) = {6};    // y = L
Transfinite Surface{1:6};
Recombine Surface{1:6};
Surface Loop(1) = {1:6};
Volume(1) = {1};
Transfinite Volume{1};

Physical Surface("contact") = {1};
Physical Surface("top") = {2};
Physical Surface("sym_x") = {3};
Physical Surface("outer_x") = {4};
Physical Surface("sym_y") = {5};
Physical Surface("outer_y") = {6};
Physical Volume("block") = {1};
