// box.geo -- a box [x0, x1] x [y0, y1] x [z0, z1] of nx nd x ny nd x nz nd equal hexahedra
// (transfinite): a gmsh body of a scene with several bodies (contact/mesh/bodies.py), whose
// cells are those of the box body {lower, upper, cells: [nx, ny, nz]} at the same nd.
//
// Parameters (gmsh -setnumber, or the body's mesh.parameters; nd: the scene's coarse nd):
//   x0 y0 z0 x1 y1 z1   the corners (default [0, 1]^3)
//   nx ny nz            cells per direction per nd (default 2)
//   nd                  refinement (default 1)
//
// Physical surfaces: "xmin" "xmax" "ymin" "ymax" "bottom" (z = z0) "top" (z = z1).
// Physical volume "box".

DefineConstant[ nd = {1, Min 1, Max 64, Step 1, Name "nd"} ];
DefineConstant[ x0 = {0, Name "x0"} ];  DefineConstant[ x1 = {1, Name "x1"} ];
DefineConstant[ y0 = {0, Name "y0"} ];  DefineConstant[ y1 = {1, Name "y1"} ];
DefineConstant[ z0 = {0, Name "z0"} ];  DefineConstant[ z1 = {1, Name "z1"} ];
DefineConstant[ nx = {2, Name "nx"} ];  DefineConstant[ ny = {2, Name "ny"} ];
DefineConstant[ nz = {2, Name "nz"} ];

Point(1) = {x0, y0, z0};
ex[] = Extrude {x1 - x0, 0, 0} { Point{1}; Layers{nx * nd}; };
ey[] = Extrude {0, y1 - y0, 0} { Curve{ex[1]}; Layers{ny * nd}; Recombine; };
ez[] = Extrude {0, 0, z1 - z0} { Surface{ey[1]}; Layers{nz * nd}; Recombine; };

// ez[]: top, volume, then the sides along the extruded curves of ey[1]
ex_ = (x1 - x0) * 1e-6;  ey_ = (y1 - y0) * 1e-6;  ez_ = (z1 - z0) * 1e-6;
Physical Surface("bottom") = {ey[1]};
Physical Surface("top") = {ez[0]};
Physical Surface("xmin") = Surface In BoundingBox {x0 - ex_, y0 - ey_, z0 - ez_, x0 + ex_, y1 + ey_, z1 + ez_};
Physical Surface("xmax") = Surface In BoundingBox {x1 - ex_, y0 - ey_, z0 - ez_, x1 + ex_, y1 + ey_, z1 + ez_};
Physical Surface("ymin") = Surface In BoundingBox {x0 - ex_, y0 - ey_, z0 - ez_, x1 + ex_, y0 + ey_, z1 + ez_};
Physical Surface("ymax") = Surface In BoundingBox {x0 - ex_, y1 - ey_, z0 - ez_, x1 + ex_, y1 + ey_, z1 + ez_};
Physical Volume("box") = {ez[1]};
