// A punch on a substrate (2D, plane strain), the half x >= 0 of both (symmetry about x = 0):
//   punch: half of the rectangle [-w, w] x [0, H], its bottom corner rounded with radius r:
//     0 <= x <= w, 0 <= y <= H, the corner (w, 0) replaced by the quarter circle of centre
//     (w - r, r); its flat bottom y = 0, 0 <= x <= w - r, lies on the substrate's top;
//   substrate: half of the rectangle [-B, B] x [-D, 0]: 0 <= x <= B, -D <= y <= 0.
// The two bodies are separate meshes: they share no node (not even along y = 0, where the
// punch's flat bottom lies on the substrate's top) and their meshes do not match there.
// Physical groups (cells): "punch" (physical surface 10), "substrate" (11).
// Physical groups (curves):
//   "punch_top"             y = H (the load)
//   "punch_bottom"          the flat bottom and the fillet (the contact surface)
//   "punch_side"            x = w, r <= y <= H (free)
//   "punch_sym"             x = 0 of the punch (symmetry roller u_x = 0)
//   "substrate_top_contact" y = 0, 0 <= x <= wt (the target)
//   "substrate_top_free"    y = 0, wt <= x <= B (free)
//   "substrate_side"        x = B (free)
//   "substrate_bottom"      y = -D (clamped)
//   "substrate_sym"         x = 0 of the substrate (symmetry roller u_x = 0)
// Mesh size: hc along the punch's bottom and the substrate's top for x <= "zone", hf within
// "near" of the fillet (where the pressure peaks), growing linearly (rate "grow") away from
// them up to hmax; mesh.size scales every size.  The contact half-width w - r = 0.45 of the
// flat part spans 45 cells of size hc, the fillet's quarter circle about 30 of size hf.
hc = 0.01;      // cell size on the contact zone
hf = 0.0025;    // cell size at the fillet
hmax = 0.1;     // cell size far from it
grow = 0.15;    // size increase per unit distance
near = 0.03;    // distance from the fillet within which the size is hf
zone = 0.6;     // the contact zone's extent in x (beyond the punch's half-width w)
w = 0.5;        // half-width of the punch
H = 0.5;        // height of the punch
r = 0.05;       // fillet radius
B = 2.0;        // half-width of the substrate
D = 2.0;        // depth of the substrate
wt = 1.0;       // extent in x of the target "substrate_top_contact"
Geometry.AutoCoherence = 0;   // the points of y = 0 stay the two bodies' own points

// punch
Point(1) = {0, 0, 0};
Point(2) = {w - r, 0, 0};     // start of the fillet
Point(3) = {w - r, r, 0};     // centre of the fillet
Point(4) = {w, r, 0};         // end of the fillet
Point(5) = {w, H, 0};
Point(6) = {0, H, 0};
Line(1) = {1, 2};             // punch_bottom, flat
Circle(2) = {2, 3, 4};        // punch_bottom, fillet
Line(3) = {4, 5};             // punch_side
Line(4) = {5, 6};             // punch_top
Line(5) = {6, 1};             // punch_sym
Curve Loop(1) = {1, 2, 3, 4, 5};
Plane Surface(1) = {1};

// substrate
Point(11) = {0, 0, 0};
Point(12) = {wt, 0, 0};
Point(13) = {B, 0, 0};
Point(14) = {B, -D, 0};
Point(15) = {0, -D, 0};
Line(11) = {11, 12};          // substrate_top_contact
Line(12) = {12, 13};          // substrate_top_free
Line(13) = {13, 14};          // substrate_side
Line(14) = {14, 15};          // substrate_bottom
Line(15) = {15, 11};          // substrate_sym
Curve Loop(11) = {-11, -12, -13, -14, -15};
Plane Surface(11) = {11};

Physical Curve("punch_bottom", 1) = {1, 2};
Physical Curve("punch_side", 2) = {3};
Physical Curve("punch_top", 3) = {4};
Physical Curve("punch_sym", 4) = {5};
Physical Curve("substrate_top_contact", 5) = {11};
Physical Curve("substrate_top_free", 6) = {12};
Physical Curve("substrate_side", 7) = {13};
Physical Curve("substrate_bottom", 8) = {14};
Physical Curve("substrate_sym", 9) = {15};
Physical Surface("punch", 10) = {1};
Physical Surface("substrate", 11) = {11};

Field[1] = Box;               // the contact zone: x <= zone, |y| <= 0 (grown by Thickness)
Field[1].VIn = hc;
Field[1].VOut = hmax;
Field[1].XMin = -1;
Field[1].XMax = zone;
Field[1].YMin = 0;
Field[1].YMax = 0;
Field[1].Thickness = (hmax - hc) / grow;
Field[2] = Distance;          // distance to the fillet
Field[2].CurvesList = {2};
Field[2].NumPointsPerCurve = 200;
Field[3] = Threshold;
Field[3].InField = 2;
Field[3].SizeMin = hf;
Field[3].SizeMax = hmax;
Field[3].DistMin = near;
Field[3].DistMax = near + (hmax - hf) / grow;
Field[4] = Min;
Field[4].FieldsList = {1, 3};
Background Field = 4;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
