// half_cylinder.geo -- lower half of a cylinder lying on its side, all-hexahedral:
//   { (x, z) : x^2 + (z - R)^2 <= R^2, z <= R } x [0, Ly],
// axis along y at height z = R; the curved face points down and touches the plane z = 0
// along the line x = 0, z = 0. Cross-section (x-z plane) in 4 structured blocks, an
// inner rectangle [-R/2, R/2] x [R/2, R] under the flat face and 3 blocks between it and
// the arc (45, 90, 45 degrees), extruded along y:
//
//        A----B----------C----D      z = R (flat face "top")
//         \   |  inner   |   /
//          \  P1--------P2  /
//           Q1            Q2         arc: cells of equal angle pi/(4 nd)
//              `--------'
//
// Parameters (gmsh -setnumber, or read_gmsh(..., parameters={...})):
//   nd   refinement: 4 nd cells along the arc, nd radially, ny along y (default 4)
//   ny   cells along y (default nd)
//   R    radius (default 1)        Ly   length along y (default 1)
//
// Physical surfaces:
//   "contact"  the curved face       "top"   the flat face z = R
//   "front"    y = 0                 "back"  y = Ly
// Physical volume "body".

DefineConstant[ nd = {4, Min 1, Max 64, Step 1, Name "nd"} ];
DefineConstant[ ny = {nd, Min 1, Max 256, Step 1, Name "ny"} ];
DefineConstant[ R = {1, Name "R"} ];
DefineConstant[ Ly = {1, Name "Ly"} ];

a = R / 2;             // half-width and depth of the inner block
s = R / Sqrt(2);

Point(1) = {0, 0, R};            // centre of the arcs
Point(2) = {-R, 0, R};           // A
Point(3) = {-a, 0, R};           // B
Point(4) = {a, 0, R};            // C
Point(5) = {R, 0, R};            // D
Point(6) = {-a, 0, R - a};       // P1
Point(7) = {a, 0, R - a};        // P2
Point(8) = {-s, 0, R - s};       // Q1
Point(9) = {s, 0, R - s};        // Q2

Line(1) = {2, 3};                // A-B
Line(2) = {3, 4};                // B-C
Line(3) = {4, 5};                // C-D
Line(4) = {3, 6};                // B-P1
Line(5) = {4, 7};                // C-P2
Line(6) = {6, 7};                // P1-P2
Line(7) = {6, 8};                // P1-Q1
Line(8) = {7, 9};                // P2-Q2
Circle(9) = {8, 1, 2};           // Q1-A   (45 degrees)
Circle(10) = {8, 1, 9};          // Q1-Q2  (90 degrees)
Circle(11) = {9, 1, 5};          // Q2-D   (45 degrees)

Transfinite Curve{1, 3, 7, 8} = nd + 1;          // radial
Transfinite Curve{4, 5, 9, 11} = nd + 1;         // 45 degrees
Transfinite Curve{2, 6, 10} = 2 * nd + 1;        // 90 degrees

// loops clockwise in (x, z), i.e. normal +y, the direction of the extrusion
Curve Loop(1) = {1, 4, 7, 9};          Plane Surface(1) = {1};     // left
Curve Loop(2) = {2, 5, -6, -4};        Plane Surface(2) = {2};     // inner
Curve Loop(3) = {6, 8, -10, -7};       Plane Surface(3) = {3};     // bottom
Curve Loop(4) = {3, -11, -8, -5};      Plane Surface(4) = {4};     // right
Transfinite Surface{1, 2, 3, 4};
Recombine Surface{1, 2, 3, 4};

// Extrude returns: [0] the far surface, [1] the volume, [2..] one surface per loop curve
e1[] = Extrude {0, Ly, 0} { Surface{1}; Layers{ny}; Recombine; };
e2[] = Extrude {0, Ly, 0} { Surface{2}; Layers{ny}; Recombine; };
e3[] = Extrude {0, Ly, 0} { Surface{3}; Layers{ny}; Recombine; };
e4[] = Extrude {0, Ly, 0} { Surface{4}; Layers{ny}; Recombine; };

Physical Surface("contact") = {e1[5], e3[4], e4[3]};
Physical Surface("top") = {e1[2], e2[2], e4[2]};
Physical Surface("front") = {1, 2, 3, 4};
Physical Surface("back") = {e1[0], e2[0], e3[0], e4[0]};
Physical Volume("body") = {e1[1], e2[1], e3[1], e4[1]};
