// The contact patch test's two stacked blocks (3D, tetrahedra): the lower cube [0, 1]^3 with
// cells of size hl, the upper cube [0, 1] x [0, 1] x [1, 2] with cells of size hu (z is the
// vertical), two separate meshes that share no node and do not match along z = 1: each cube
// has its own points, lines and faces (tags o + 1, ... with o = 0 for the lower cube and
// o = 100 for the upper one), the two faces at z = 1 are distinct.
// Physical groups (cells): "lower" (physical volume 20), "upper" (21).
// Physical groups (faces), for each block b in lower, upper:
//   "lower_bottom" z = 0, "lower_top" z = 1 (the lower cube's side of the interface),
//   "upper_bottom" z = 1 (the upper cube's side of the interface), "upper_top" z = 2,
//   "b_left" x = 0 and "b_front" y = 0 (rollers: the two symmetry planes),
//   "b_right" x = 1 and "b_back" y = 1 (free).
hl = 1 / 5;     // cell size of the lower cube
hu = 1 / 3;     // cell size of the upper cube
Geometry.AutoCoherence = 0;   // the coincident points and faces at z = 1 stay distinct
sizes[] = {hl, hu};

For k In {0 : 1}
  o = 100 * k;                // the cube's tag offset
  z0 = k;                     // the cube's bottom
  lc = sizes[k];
  Point(o + 1) = {0, 0, z0, lc};
  Point(o + 2) = {1, 0, z0, lc};
  Point(o + 3) = {1, 1, z0, lc};
  Point(o + 4) = {0, 1, z0, lc};
  Point(o + 5) = {0, 0, z0 + 1, lc};
  Point(o + 6) = {1, 0, z0 + 1, lc};
  Point(o + 7) = {1, 1, z0 + 1, lc};
  Point(o + 8) = {0, 1, z0 + 1, lc};
  For i In {1 : 4}            // the bottom square, the top square, the vertical edges
    Line(o + i) = {o + i, o + i % 4 + 1};
    Line(o + 4 + i) = {o + 4 + i, o + 4 + i % 4 + 1};
    Line(o + 8 + i) = {o + i, o + 4 + i};
  EndFor
  Curve Loop(o + 1) = {o + 4, o + 9, -(o + 8), -(o + 12)};     // left   x = 0
  Curve Loop(o + 2) = {o + 2, o + 11, -(o + 6), -(o + 10)};    // right  x = 1
  Curve Loop(o + 3) = {o + 1, o + 10, -(o + 5), -(o + 9)};     // front  y = 0
  Curve Loop(o + 4) = {o + 3, o + 12, -(o + 7), -(o + 11)};    // back   y = 1
  Curve Loop(o + 5) = {o + 1, o + 2, o + 3, o + 4};            // bottom z = z0
  Curve Loop(o + 6) = {o + 5, o + 6, o + 7, o + 8};            // top    z = z0 + 1
  For i In {1 : 6}
    Plane Surface(o + i) = {o + i};
  EndFor
  Surface Loop(o + 1) = {o + 1 : o + 6};
  Volume(o + 1) = {o + 1};
EndFor

Physical Surface("lower_left", 1) = {1};
Physical Surface("lower_right", 2) = {2};
Physical Surface("lower_front", 3) = {3};
Physical Surface("lower_back", 4) = {4};
Physical Surface("lower_bottom", 5) = {5};
Physical Surface("lower_top", 6) = {6};
Physical Surface("upper_left", 7) = {101};
Physical Surface("upper_right", 8) = {102};
Physical Surface("upper_front", 9) = {103};
Physical Surface("upper_back", 10) = {104};
Physical Surface("upper_bottom", 11) = {105};
Physical Surface("upper_top", 12) = {106};
Physical Volume("lower", 20) = {1};
Physical Volume("upper", 21) = {101};
