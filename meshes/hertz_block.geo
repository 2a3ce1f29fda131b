// hertz_block.geo -- quarter model of a nearly half-space block for Hertz-type contact
// centred at the origin: [0, L] x [0, L] x [0, H], all-hexahedral (extruded layers).
// A uniform core [0, b]^3 of n cells per direction (n = 2 nd) resolves the contact
// zone; outside it the cells grow geometrically (ratio r, m cells) out to L and H.
//
// Parameters (scene mesh.parameters, or gmsh -setnumber):
//   nd  core refinement, n = 2 nd cells across b (default 4)
//   b   core size (default 1)     L  side in x and y (default 8)     H  height (default 8)
//   m   cells outside the core per direction (default 8)
//   r   growth ratio of the outer cells (default 1.35)
//
// Physical surfaces:
//   "contact"  z = 0    "top"  z = H    "sym_x"  x = 0    "sym_y"  y = 0
//   "outer_x"  x = L    "outer_y"  y = L
// Physical volume "block".

DefineConstant[ nd = {4, Min 1, Max 64, Step 1, Name "nd"} ];
DefineConstant[ b = {1, Name "b"} ];
DefineConstant[ L = {8, Name "L"} ];
DefineConstant[ H = {8, Name "H"} ];
DefineConstant[ m = {8, Min 1, Max 64, Step 1, Name "m"} ];
DefineConstant[ r = {1.35, Min 1, Max 3, Name "r"} ];

n = 2 * nd;
// cumulative layer positions (fractions of the extrusion length) along x, y (len L), z (len H)
For dir In {0:1}
  len = (dir == 0) ? L : H;
  t[] = {};
  For i In {1:n}
    t[] += {i * b / n / len};
  EndFor
  For i In {1:m}
    s = (r == 1) ? i / m : (r^i - 1) / (r^m - 1);
    t[] += {(b + (len - b) * s) / len};
  EndFor
  If (dir == 0)
    tl[] = t[];
  Else
    tz[] = t[];
  EndIf
EndFor
one[] = {};
For i In {1:n + m}
  one[] += {1};
EndFor

Point(1) = {0, 0, 0};
ex[] = Extrude {L, 0, 0} { Point{1}; Layers{one[], tl[]}; };          // line along x
ey[] = Extrude {0, L, 0} { Line{ex[1]}; Layers{one[], tl[]}; Recombine; };   // z = 0 face
ez[] = Extrude {0, 0, H} { Surface{ey[1]}; Layers{one[], tz[]}; Recombine; };
// ez[]: 0 top, 1 volume, 2.. lateral faces from the edges of ey[1] (y = 0, x = L, y = L, x = 0)

Physical Surface("contact") = {ey[1]};
Physical Surface("top") = {ez[0]};
Physical Surface("sym_y") = {ez[2]};
Physical Surface("outer_x") = {ez[3]};
Physical Surface("outer_y") = {ez[4]};
Physical Surface("sym_x") = {ez[5]};
Physical Volume("block") = {ez[1]};
