// Half of a two-material punch 0 <= x <= 0.5, 0 <= y <= 0.5 (symmetric about x = 0), its
// bottom right corner rounded with radius r = 0.1: a soft viscoplastic foot 0 <= y <= yi
// under a stiff elastic cap yi <= y <= 0.5, bonded along y = yi (the cells of the two
// physical surfaces share the interface's nodes).
// Physical groups: "base" the bottom y = 0 and the fillet arc (contact), "top" the side
// y = 0.5 (prescribed displacement), "sym" the side x = 0 (symmetry roller), "side" the
// sides x = 0.5 (free); the cells: "foot" (physical surface 10) and "cap" (11).
// Mesh size: hb within "near" of the base, growing linearly to hmax; mesh.size scales it.
hb = 0.01;      // cell size at the base
hmax = 0.05;    // cell size far from it
near = 0.04;    // width of the band of size hb along the base
grow = 0.3;     // size increase per unit distance beyond it
w = 0.5;        // half-width
H = 0.5;        // height
yi = 0.25;      // height of the interface between foot and cap
r = 0.1;        // fillet radius

Point(1) = {0, 0, 0};
Point(2) = {w - r, 0, 0};     // start of the fillet
Point(3) = {w - r, r, 0};     // centre of the fillet
Point(4) = {w, r, 0};         // end of the fillet
Point(5) = {w, yi, 0};
Point(6) = {0, yi, 0};
Point(7) = {w, H, 0};
Point(8) = {0, H, 0};
Line(1) = {1, 2};             // bottom
Circle(2) = {2, 3, 4};        // fillet
Line(3) = {4, 5};             // side of the foot
Line(4) = {5, 6};             // interface
Line(5) = {6, 1};             // sym, foot
Line(6) = {5, 7};             // side of the cap
Line(7) = {7, 8};             // top
Line(8) = {8, 6};             // sym, cap
Curve Loop(1) = {1, 2, 3, 4, 5};
Plane Surface(1) = {1};
Curve Loop(2) = {-4, 6, 7, 8};
Plane Surface(2) = {2};

Physical Curve("base", 1) = {1, 2};
Physical Curve("top", 2) = {7};
Physical Curve("sym", 3) = {5, 8};
Physical Curve("side", 4) = {3, 6};
Physical Surface("foot", 10) = {1};
Physical Surface("cap", 11) = {2};

Field[1] = Distance;          // distance to the base
Field[1].CurvesList = {1, 2};
Field[1].NumPointsPerCurve = 200;
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
