// ball.geo -- the "ball" of runs/scenes/hertz_two_bodies_gmsh.yaml, quarter model: the
// body over [0, L]^2 between its curved lower face z = (x^2 + y^2) / (2 R) (the gap of a
// sphere of radius R, as hertz_two_bodies.yaml's lower_surface) and its flat top z = H,
// all-hexahedral (transfinite), graded toward the contact point (0, 0, 0): nx nd cells
// along x and y whose sizes grow by rx from x = 0 to x = L (gmsh's Progression
// rx^(1 / (nx nd)) by arc length: mesh.grading's progression rx), nz nd along z growing
// by rz from the lower face up. The lower face's four edges are quadratic Bezier curves,
// the paraboloid's sections exactly (x or y linear in the curve's parameter); the face
// itself is gmsh's transfinite (Coons) interpolation of its edges, which holds
// z = g(x) + h(y) exactly: the CAD surface is the paraboloid (to rounding), and the
// refined levels' vertices moved onto it (contact/mesh/cad.py) lie on the paraboloid.
//
// Parameters (gmsh -setnumber, or the body's mesh.parameters; nd: the scene's coarse nd):
//   nd (default 1)   L, H (2, 2)   R (10)   nx, nz (6, 4)   rx, rz (6, 5)
//
// Physical surfaces:
//   "contact"  the curved lower face    "top"      z = H
//   "sym_x"    x = 0                    "outer_x"  x = L
//   "sym_y"    y = 0                    "outer_y"  y = L
// Physical volume "ball".

DefineConstant[ nd = {1, Min 1, Max 64, Step 1, Name "nd"} ];
DefineConstant[ L = {2, Name "L"} ];    DefineConstant[ H = {2, Name "H"} ];
DefineConstant[ R = {10, Name "R"} ];
DefineConstant[ nx = {6, Name "nx"} ];  DefineConstant[ nz = {4, Name "nz"} ];
DefineConstant[ rx = {6, Name "rx"} ];  DefineConstant[ rz = {5, Name "rz"} ];

Point(1) = {0, 0, 0};  Point(2) = {L, 0, L^2 / (2 * R)};
Point(3) = {L, L, L^2 / R};  Point(4) = {0, L, L^2 / (2 * R)};
Point(5) = {0, 0, H};  Point(6) = {L, 0, H};  Point(7) = {L, L, H};  Point(8) = {0, L, H};

// the lower face's edges, each away from x = 0 or y = 0: quadratic Bezier curves, which
// are the parabolas z = (x^2 + y^2) / (2 R) exactly (control points at the ends and at the
// middle of x or y with the end's z: the tangents' intersection)
Point(9) = {L / 2, 0, 0};  Point(10) = {L, L / 2, L^2 / (2 * R)};
Point(11) = {L / 2, L, L^2 / (2 * R)};  Point(12) = {0, L / 2, 0};
Bezier(1) = {1, 9, 2};  Bezier(2) = {2, 10, 3};  Bezier(3) = {4, 11, 3};  Bezier(4) = {1, 12, 4};
Line(5) = {5, 6};  Line(6) = {6, 7};  Line(7) = {8, 7};  Line(8) = {5, 8};     // top
Line(9) = {1, 5};  Line(10) = {2, 6}; Line(11) = {3, 7}; Line(12) = {4, 8};    // up
Transfinite Curve{1:8} = nx * nd + 1 Using Progression rx^(1 / (nx * nd));
Transfinite Curve{9:12} = nz * nd + 1 Using Progression rz^(1 / (nz * nd));

Curve Loop(1) = {1, 2, -3, -4};    Surface(1) = {1};          // the curved lower face
Curve Loop(2) = {5, 6, -7, -8};    Plane Surface(2) = {2};    // z = H
Curve Loop(3) = {4, 12, -8, -9};   Plane Surface(3) = {3};    // x = 0
Curve Loop(4) = {2, 11, -6, -10};  Plane Surface(4) = {4};    // x = L
Curve Loop(5) = {1, 10, -5, -9};   Plane Surface(5) = {5};    // y = 0
Curve Loop(6) = {3, 11, -7, -12};  Plane Surface(6) = {6};    // y = L
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
Physical Volume("ball") = {1};
