// Half of a rectangular punch 0 <= x <= 0.5, 0 <= y <= 0.5 (symmetric about x = 0) whose
// bottom right corner is rounded with radius r = 0.1.
// Physical groups: "base" the bottom y = 0 and the fillet arc (contact), "top" the side
// y = 0.5 (prescribed displacement), "sym" the side x = 0 (symmetry roller), "side" the side
// x = 0.5 (free), "body" the punch.
// Mesh size: hb within "near" of the base, growing linearly to hmax; mesh.size scales it.
hb = 0.004;     // cell size at the base
hmax = 0.03;    // cell size far from it
near = 0.05;    // width of the band of size hb along the base
grow = 0.2;     // size increase per unit distance beyond it
w = 0.5;        // half-width
H = 0.5;        // height
r = 0.1;        // fillet radius

Point(1) = {0, 0, 0};
Point(2) = {w - r, 0, 0};     // start of the fillet
Point(3) = {w - r, r, 0};     // centre of the fillet
Point(4) = {w, r, 0};         // end of the fillet
Point(5) = {w, H, 0};
Point(6) = {0, H, 0};
Line(1) = {1, 2};             // bottom
Circle(2) = {2, 3, 4};        // fillet
Line(3) = {4, 5};             // side
Line(4) = {5, 6};             // top
Line(5) = {6, 1};             // sym
Curve Loop(1) = {1, 2, 3, 4, 5};
Plane Surface(1) = {1};

Physical Curve("base", 1) = {1, 2};
Physical Curve("top", 2) = {4};
Physical Curve("sym", 3) = {5};
Physical Curve("side", 4) = {3};
Physical Surface("body", 10) = {1};

Field[1] = Distance;          // distance to the base
Field[1].CurvesList = {1, 2};
Field[1].NumPointsPerCurve = 500;
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = hb;
Field[2].SizeMax = hmax;
Field[2].DistMin = near;
Field[2].DistMax = near + (hmax - hb) / grow;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
