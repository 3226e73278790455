// The contact patch test's two stacked blocks (2D): the lower block [0, 1] x [0, 1] with
// cells of size hl, the upper block [0, 1] x [1, 2] with cells of size hu, two separate
// meshes that share no node and do not match along y = 1 (the lower top's nodes at x = k hl,
// the upper bottom's at x = k hu: they meet at x = 0 and x = 1 only).
// Physical groups (cells): "lower" (physical surface 10), "upper" (11).
// Physical groups (curves): "lower_bottom" y = 0, "lower_top" y = 1 (the lower block's
// side of the interface), "lower_left" x = 0 (roller), "lower_right" x = 1 (free);
// "upper_bottom" y = 1 (the upper block's side of the interface), "upper_top" y = 2,
// "upper_left" x = 0 (roller), "upper_right" x = 1 (free).
hl = 1 / 7;     // cell size of the lower block
hu = 1 / 4;     // cell size of the upper block
Geometry.AutoCoherence = 0;   // the corners at y = 1 stay each block's own points

Point(1) = {0, 0, 0, hl};
Point(2) = {1, 0, 0, hl};
Point(3) = {1, 1, 0, hl};
Point(4) = {0, 1, 0, hl};
Line(1) = {1, 2};             // lower_bottom
Line(2) = {2, 3};             // lower_right
Line(3) = {3, 4};             // lower_top
Line(4) = {4, 1};             // lower_left
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};

Point(11) = {0, 1, 0, hu};
Point(12) = {1, 1, 0, hu};
Point(13) = {1, 2, 0, hu};
Point(14) = {0, 2, 0, hu};
Line(11) = {11, 12};          // upper_bottom
Line(12) = {12, 13};          // upper_right
Line(13) = {13, 14};          // upper_top
Line(14) = {14, 11};          // upper_left
Curve Loop(11) = {11, 12, 13, 14};
Plane Surface(11) = {11};

Physical Curve("lower_bottom", 1) = {1};
Physical Curve("lower_right", 2) = {2};
Physical Curve("lower_top", 3) = {3};
Physical Curve("lower_left", 4) = {4};
Physical Curve("upper_bottom", 5) = {11};
Physical Curve("upper_right", 6) = {12};
Physical Curve("upper_top", 7) = {13};
Physical Curve("upper_left", 8) = {14};
Physical Surface("lower", 10) = {1};
Physical Surface("upper", 11) = {11};
