// Hertz contact of a cylinder: the quarter disc x >= 0, y <= 1, x^2 + (y - 1)^2 <= 1
// (radius R = 1, centre (0, 1)), touching the plane y = 0 at its bottom point (0, 0).
// Physical groups: "arc" the circular arc from (0, 0) to (1, 1) (contact), "top" the side
// y = 1 (pushed down), "sym" the side x = 0 (symmetry roller), "body" the disc.
// Mesh size: hc on the arc within 0.3 of the bottom point, growing linearly (rate "grow")
// away from the arc and from the bottom point to hmax; mesh.size scales every size.
hc = 0.003;     // cell size on the contact zone
hmax = 0.05;    // cell size far from it
grow = 0.15;    // size increase per unit distance
zone = 0.3;     // half-length of the finely meshed part of the arc

Point(1) = {0, 0, 0};     // bottom point: first contact
Point(2) = {0, 1, 0};     // centre
Point(3) = {1, 1, 0};
Circle(1) = {1, 2, 3};    // arc
Line(2) = {3, 2};         // top
Line(3) = {2, 1};         // sym
Curve Loop(1) = {1, 2, 3};
Plane Surface(1) = {1};

Physical Curve("arc", 1) = {1};
Physical Curve("top", 2) = {2};
Physical Curve("sym", 3) = {3};
Physical Surface("body", 10) = {1};

Field[1] = Distance;          // distance to the arc
Field[1].CurvesList = {1};
Field[1].NumPointsPerCurve = 2000;
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = hc;
Field[2].SizeMax = hmax;
Field[2].DistMin = 0;
Field[2].DistMax = (hmax - hc) / grow;
Field[3] = Distance;          // distance to the bottom point
Field[3].PointsList = {1};
Field[4] = Threshold;
Field[4].InField = 3;
Field[4].SizeMin = hc;
Field[4].SizeMax = hmax;
Field[4].DistMin = zone;
Field[4].DistMax = zone + (hmax - hc) / grow;
Field[5] = Max;               // fine only near the arc and near the bottom point
Field[5].FieldsList = {2, 4};
Background Field = 5;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
