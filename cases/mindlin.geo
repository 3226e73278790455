// Cattaneo-Mindlin: a half cylinder of radius R = 1 pressed onto a block and then sheared
// (2D, plane strain), the whole model (the shear is antisymmetric: no symmetry line):
//   cylinder: the half disc y <= R, x^2 + (y - R)^2 <= R^2 (the lower half of the disc of
//     radius R centred at (0, R), cut along its diameter y = R), touching the block at the
//     origin;
//   block: the rectangle [-B, B] x [-D, 0] (top y = 0).
// The two bodies are separate meshes: they share no node (not even the origin, where both
// have a vertex) and their meshes do not match along the contact.
// Physical groups (cells): "cylinder" (physical surface 10), "block" (11).
// Physical groups (curves):
//   "cylinder_top"      y = R, the flat side of the cylinder (the loads P and Q)
//   "cylinder_arc"      the arc within "theta" of its bottom point on either side (the
//                       contact surface)
//   "cylinder_free"     the rest of the arc, both sides (free)
//   "block_top_contact" the middle |x| <= "wt" of the block's top (the target)
//   "block_top_free"    the rest of the block's top, both sides (free)
//   "block_sides"       x = -B and x = B (free)
//   "block_bottom"      y = -D (clamped)
// Mesh size: hc on the contact surface and the target within "zone" of the origin, growing
// linearly (rate "grow") away from them and, beyond "zone", from the origin, up to hmax;
// mesh.size scales every size.  Sized for a contact half-width a up to about 0.12 (Hertz,
// cylinder on a plane: a = 0.1 with, e.g., E = 1000, nu = 0.3 for both bodies at
// P = 4.32 N/m per unit length): a = 0.1 spans 40 cells of size hc on each surface, so that
// the stick zone's half-width c = a sqrt(1 - Q / (mu P)) is resolved to a fortieth of a.
hc = 0.0025;    // cell size on the contact zone
hmax = 0.15;    // cell size far from it
grow = 0.12;    // size increase per unit distance
zone = 0.25;    // radius (about the origin) of the finely meshed part of the surfaces
R = 1.0;        // radius of the cylinder
B = 3.0;        // half-width of the block
D = 3.0;        // depth of the block
theta = 30 * Pi / 180;    // angle of the contact arc "cylinder_arc" from the bottom point
wt = 0.8;       // half-width of the target "block_top_contact"
Geometry.AutoCoherence = 0;   // the two vertices at the origin stay two points

// cylinder
Point(1) = {0, 0, 0};                                     // bottom point: first contact
Point(2) = {R * Sin(theta), R - R * Cos(theta), 0};       // ends of the contact arc
Point(3) = {-R * Sin(theta), R - R * Cos(theta), 0};
Point(4) = {R, R, 0};
Point(5) = {-R, R, 0};
Point(6) = {0, R, 0};                                     // centre
Circle(1) = {3, 6, 1};        // cylinder_arc, left half
Circle(2) = {1, 6, 2};        // cylinder_arc, right half
Circle(3) = {2, 6, 4};        // cylinder_free, right
Line(4) = {4, 5};             // cylinder_top
Circle(5) = {5, 6, 3};        // cylinder_free, left
Curve Loop(1) = {1, 2, 3, 4, 5};
Plane Surface(1) = {1};

// block
Point(11) = {0, 0, 0};        // the top's point under the cylinder's bottom point
Point(12) = {wt, 0, 0};
Point(13) = {B, 0, 0};
Point(14) = {B, -D, 0};
Point(15) = {-B, -D, 0};
Point(16) = {-B, 0, 0};
Point(17) = {-wt, 0, 0};
Line(11) = {17, 11};          // block_top_contact, left half
Line(12) = {11, 12};          // block_top_contact, right half
Line(13) = {12, 13};          // block_top_free, right
Line(14) = {13, 14};          // block_sides, right
Line(15) = {14, 15};          // block_bottom
Line(16) = {15, 16};          // block_sides, left
Line(17) = {16, 17};          // block_top_free, left
Curve Loop(11) = {-11, -12, -13, -14, -15, -16, -17};
Plane Surface(11) = {11};

Physical Curve("cylinder_arc", 1) = {1, 2};
Physical Curve("cylinder_free", 2) = {3, 5};
Physical Curve("cylinder_top", 3) = {4};
Physical Curve("block_top_contact", 4) = {11, 12};
Physical Curve("block_top_free", 5) = {13, 17};
Physical Curve("block_sides", 6) = {14, 16};
Physical Curve("block_bottom", 7) = {15};
Physical Surface("cylinder", 10) = {1};
Physical Surface("block", 11) = {11};

Field[1] = Distance;          // distance to the arc and the block's top
Field[1].CurvesList = {1, 2, 3, 5, 11, 12, 13, 17};
Field[1].NumPointsPerCurve = 2000;
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = hc;
Field[2].SizeMax = hmax;
Field[2].DistMin = 0;
Field[2].DistMax = (hmax - hc) / grow;
Field[3] = Distance;          // distance to the origin
Field[3].PointsList = {1, 11};
Field[4] = Threshold;
Field[4].InField = 3;
Field[4].SizeMin = hc;
Field[4].SizeMax = hmax;
Field[4].DistMin = zone;
Field[4].DistMax = zone + (hmax - hc) / grow;
Field[5] = Max;               // fine only near the surfaces and near the origin
Field[5].FieldsList = {2, 4};
Background Field = 5;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
