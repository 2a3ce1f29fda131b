// ring.geo -- a quarter of a thick-walled tube: r0 <= r <= r1, 0 <= angle <= 90 degrees
// (x, y >= 0), z0 <= z <= z1, all-hexahedral (a radial line swept about z, then extruded
// along z): nr nd cells across the wall, nt nd along the arc, nz along z. For the shrink
// fit of runs/scenes/shrink_fit.yaml (two such tubes, the inner one's outer face the slave
// of a curved contact pair) and tests/fem/test_pairs_curved.py.
//
// Parameters (gmsh -setnumber, or the body's mesh.parameters; nd: the scene's coarse nd):
//   r0 r1       the radii (default 1, 2)
//   z0 z1       the ends (default 0, 0.25)
//   nr nt nz    cells across the wall, along the arc (per nd) and along z (default 2, 6, 1)
//   nd          refinement (default 1)
//
// Physical surfaces: "inner" (r = r0), "outer" (r = r1), "xmin" (x = 0), "ymin" (y = 0),
// "bottom" (z = z0), "top" (z = z1). Physical volume "tube".

DefineConstant[ nd = {1, Min 1, Max 64, Step 1, Name "nd"} ];
DefineConstant[ r0 = {1, Name "r0"} ];  DefineConstant[ r1 = {2, Name "r1"} ];
DefineConstant[ z0 = {0, Name "z0"} ];  DefineConstant[ z1 = {0.25, Name "z1"} ];
DefineConstant[ nr = {2, Name "nr"} ];  DefineConstant[ nt = {6, Name "nt"} ];
DefineConstant[ nz = {1, Name "nz"} ];

Point(1) = {r0, 0, z0};
Point(2) = {r1, 0, z0};
Line(1) = {1, 2};
Transfinite Curve{1} = nr * nd + 1;
es[] = Extrude { {0, 0, 1}, {0, 0, 0}, Pi / 2 } { Curve{1}; Layers{nt * nd}; Recombine; };
ev[] = Extrude {0, 0, z1 - z0} { Surface{es[1]}; Layers{nz}; Recombine; };

e = 1e-6 * r1;
Physical Surface("bottom") = {es[1]};
Physical Surface("top") = {ev[0]};
Physical Surface("inner") = Surface In BoundingBox {-e, -e, z0 - e, r0 + e, r0 + e, z1 + e};
Physical Surface("xmin") = Surface In BoundingBox {-e, -e, z0 - e, e, r1 + e, z1 + e};
Physical Surface("ymin") = Surface In BoundingBox {-e, -e, z0 - e, r1 + e, e, z1 + e};
Physical Surface("outer") = {ev[3]};
Physical Volume("tube") = {ev[1]};
