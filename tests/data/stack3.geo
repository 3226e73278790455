// Three stacked blocks (2D) for two contact pairs with different laws: the bottom block
// [0, 1] x [0, 1] (cells hb), the middle block [0, 1] x [1, 2] (cells hm), the top block
// [0, 1] x [2, 3] (cells ht); three separate meshes that share no node and do not match
// at y = 1 and y = 2.
// Physical groups (cells): "bottom" (20), "middle" (21), "top" (22).
// Physical groups (curves): "bottom_bottom" y = 0, "bottom_top" y = 1, "middle_bottom"
// y = 1, "middle_top" y = 2, "middle_left" x = 0 (1 <= y <= 2), "top_bottom" y = 2,
// "top_top" y = 3.  The finer side of each interface (bottom_top, middle_top) is the
// surface of its pair.
hb = 1 / 7;
hm = 1 / 5;
ht = 1 / 3;
Geometry.AutoCoherence = 0;   // the corners at y = 1 and y = 2 stay each block's own

Point(1) = {0, 0, 0, hb};
Point(2) = {1, 0, 0, hb};
Point(3) = {1, 1, 0, hb};
Point(4) = {0, 1, 0, hb};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};             // bottom_top
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};

Point(11) = {0, 1, 0, hm};
Point(12) = {1, 1, 0, hm};
Point(13) = {1, 2, 0, hm};
Point(14) = {0, 2, 0, hm};
Line(11) = {11, 12};          // middle_bottom
Line(12) = {12, 13};
Line(13) = {13, 14};          // middle_top
Line(14) = {14, 11};          // middle_left
Curve Loop(11) = {11, 12, 13, 14};
Plane Surface(11) = {11};

Point(21) = {0, 2, 0, ht};
Point(22) = {1, 2, 0, ht};
Point(23) = {1, 3, 0, ht};
Point(24) = {0, 3, 0, ht};
Line(21) = {21, 22};          // top_bottom
Line(22) = {22, 23};
Line(23) = {23, 24};          // top_top
Line(24) = {24, 21};
Curve Loop(21) = {21, 22, 23, 24};
Plane Surface(21) = {21};

Physical Curve("bottom_bottom", 1) = {1};
Physical Curve("bottom_top", 2) = {3};
Physical Curve("middle_bottom", 3) = {11};
Physical Curve("middle_top", 4) = {13};
Physical Curve("middle_left", 5) = {14};
Physical Curve("top_bottom", 6) = {21};
Physical Curve("top_top", 7) = {23};
Physical Surface("bottom", 20) = {1};
Physical Surface("middle", 21) = {11};
Physical Surface("top", 22) = {21};
