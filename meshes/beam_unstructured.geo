// beam_unstructured.geo -- the paper's beam [0,3] x [0,1] x [0,1], all-hexahedral but not
// structured: its x-z section (y = 0) an unstructured quadrilateral mesh (gmsh's
// Frontal-Delaunay for quads, recombined), about 1 / nd in size, extruded along y in nd
// layers. Its vertices lie on no lattice of planes in x and z: a mesh a per-axis map
// grades (mesh.grading; contact/mesh/grading.py box_planes), as the run's indicator says.
//
// Parameters (gmsh -setnumber, or the scene's mesh.parameters):
//   nd   cells per unit length (default 2)
//
// Physical surfaces (as beam.geo's):
//   "clamped"  x = 0        "end"  x = 3
//   "contact"  z = 0        "top"  z = 1
//   "sides"    y = 0 and y = 1
// Physical volume "beam".

DefineConstant[ nd = {2, Min 1, Max 64, Step 1, Name "nd"} ];

h = 1.0 / nd;
Point(1) = {0, 0, 0, h};
Point(2) = {3, 0, 0, h};
Point(3) = {3, 0, 1, h};
Point(4) = {0, 0, 1, h};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Mesh.Algorithm = 8;                 // Frontal-Delaunay for quads
Mesh.RecombinationAlgorithm = 1;    // Blossom
Recombine Surface{1};
ev[] = Extrude {0, 1, 0} { Surface{1}; Layers{nd}; Recombine; };

eps = 1e-6;
Physical Surface("clamped") = Surface In BoundingBox {-eps, -eps, -eps, eps, 1 + eps, 1 + eps};
Physical Surface("end") = Surface In BoundingBox {3 - eps, -eps, -eps, 3 + eps, 1 + eps, 1 + eps};
Physical Surface("contact") = Surface In BoundingBox {-eps, -eps, -eps, 3 + eps, 1 + eps, eps};
Physical Surface("top") = Surface In BoundingBox {-eps, -eps, 1 - eps, 3 + eps, 1 + eps, 1 + eps};
Physical Surface("sides") = {Surface In BoundingBox {-eps, -eps, -eps, 3 + eps, eps, 1 + eps},
                             Surface In BoundingBox {-eps, 1 - eps, -eps, 3 + eps, 1 + eps, 1 + eps}};
Physical Volume("beam") = {ev[1]};
