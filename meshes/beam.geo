// beam.geo -- the paper's beam [0,3] x [0,1] x [0,1], all-hexahedral and structured:
// 3 nd x nd x nd equal cubes (extruded point -> line -> square -> box with Layers and
// Recombine). For nd = 2 the nodes are those of the box mesh 6 x 2 x 2.
//
// Parameters (override with gmsh -setnumber nd 4, or contact.gmshio.read_gmsh(...,
// parameters={"nd": 4})):
//   nd   cells per unit length (default 2)
//
// Physical surfaces:
//   "clamped"  x = 0        "end"  x = 3
//   "contact"  z = 0        "top"  z = 1
//   "sides"    y = 0 and y = 1
// Physical volume "beam".

DefineConstant[ nd = {2, Min 1, Max 64, Step 1, Name "nd"} ];

Point(1) = {0, 0, 0};
ex[] = Extrude {3, 0, 0} { Point{1}; Layers{3 * nd}; };
ey[] = Extrude {0, 1, 0} { Curve{ex[1]}; Layers{nd}; Recombine; };
ez[] = Extrude {0, 0, 1} { Surface{ey[1]}; Layers{nd}; Recombine; };

eps = 1e-6;
Physical Surface("clamped") = Surface In BoundingBox {-eps, -eps, -eps, eps, 1 + eps, 1 + eps};
Physical Surface("end") = Surface In BoundingBox {3 - eps, -eps, -eps, 3 + eps, 1 + eps, 1 + eps};
Physical Surface("contact") = Surface In BoundingBox {-eps, -eps, -eps, 3 + eps, 1 + eps, eps};
Physical Surface("top") = Surface In BoundingBox {-eps, -eps, 1 - eps, 3 + eps, 1 + eps, 1 + eps};
Physical Surface("sides") = {Surface In BoundingBox {-eps, -eps, -eps, 3 + eps, eps, 1 + eps},
                             Surface In BoundingBox {-eps, 1 - eps, -eps, 3 + eps, 1 + eps, 1 + eps}};
Physical Volume("beam") = {ez[1]};
