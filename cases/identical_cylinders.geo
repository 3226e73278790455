// Two identical cylinders of radius R = 1 touching at the origin (2D, plane strain), the
// whole model (both sides of x = 0: no symmetry roller), mirror images of each other in the
// plane y = 0:
//   upper body: the half disc y <= R, x^2 + (y - R)^2 <= R^2 (the lower half of the disc of
//     radius R centred at (0, R), cut along its diameter y = R);
//   lower body: its mirror image, the half disc y >= -R, x^2 + (y + R)^2 <= R^2.
// The lower body is written out as the upper one with y -> -y (points 11-16, curves 11-15),
// with the same size field: gmsh 4.8 then makes the lower mesh the mirror image of the upper
// one (every node at the mirror of an upper node, to round-off), so the discrete problem is
// exactly symmetric about y = 0 under a pure normal approach.  The two bodies are separate
// meshes: they share no node (not even the origin, where both have a vertex).
// Physical groups (cells): "upper" (physical surface 10), "lower" (11).
// Physical groups (curves):
//   "upper_top"    y = R, the flat side of the upper body (the loads P and Q)
//   "upper_arc"    the upper arc within "theta" of its bottom point on either side (the
//                  contact surface)
//   "upper_free"   the rest of the upper arc, both sides (free)
//   "lower_bottom" y = -R, the flat side of the lower body (clamped)
//   "lower_arc"    the lower arc within "theta" of its top point on either side (the target)
//   "lower_free"   the rest of the lower arc, both sides (free)
// Mesh size: hc on both arcs within "zone" of the origin, growing linearly (rate "grow")
// away from the arcs and, beyond "zone", from the origin, up to hmax; mesh.size scales every
// size.  Sized for a contact half-width a up to about 0.12 (Hertz, two identical cylinders:
// R* = R / 2, E* = E / (2 (1 - nu^2)); a = 0.1 with E = 1000, nu = 0.3 at P = 8.6 N/m per
// unit length): a = 0.1 spans 40 cells of size hc on each surface.
hc = 0.0025;    // cell size on the contact zone
hmax = 0.15;    // cell size far from it
grow = 0.12;    // size increase per unit distance
zone = 0.25;    // radius (about the origin) of the finely meshed part of the arcs
R = 1.0;        // radius of both cylinders
theta = 30 * Pi / 180;    // angle of the arcs "upper_arc" and "lower_arc" from the origin
Geometry.AutoCoherence = 0;   // the two vertices at the origin stay two points

// upper body
Point(1) = {0, 0, 0};                                     // bottom point: first contact
Point(2) = {R * Sin(theta), R - R * Cos(theta), 0};       // ends of the contact arc
Point(3) = {-R * Sin(theta), R - R * Cos(theta), 0};
Point(4) = {R, R, 0};
Point(5) = {-R, R, 0};
Point(6) = {0, R, 0};                                     // centre
Circle(1) = {3, 6, 1};        // upper_arc, left half
Circle(2) = {1, 6, 2};        // upper_arc, right half
Circle(3) = {2, 6, 4};        // upper_free, right
Line(4) = {4, 5};             // upper_top
Circle(5) = {5, 6, 3};        // upper_free, left
Curve Loop(1) = {1, 2, 3, 4, 5};
Plane Surface(1) = {1};

// lower body: the same with y -> -y
Point(11) = {0, 0, 0};
Point(12) = {R * Sin(theta), -(R - R * Cos(theta)), 0};
Point(13) = {-R * Sin(theta), -(R - R * Cos(theta)), 0};
Point(14) = {R, -R, 0};
Point(15) = {-R, -R, 0};
Point(16) = {0, -R, 0};
Circle(11) = {13, 16, 11};    // lower_arc, left half
Circle(12) = {11, 16, 12};    // lower_arc, right half
Circle(13) = {12, 16, 14};    // lower_free, right
Line(14) = {14, 15};          // lower_bottom
Circle(15) = {15, 16, 13};    // lower_free, left
Curve Loop(11) = {11, 12, 13, 14, 15};
Plane Surface(11) = {11};

Physical Curve("upper_arc", 1) = {1, 2};
Physical Curve("upper_free", 2) = {3, 5};
Physical Curve("upper_top", 3) = {4};
Physical Curve("lower_arc", 4) = {11, 12};
Physical Curve("lower_free", 5) = {13, 15};
Physical Curve("lower_bottom", 6) = {14};
Physical Surface("upper", 10) = {1};
Physical Surface("lower", 11) = {11};

Field[1] = Distance;          // distance to the arcs
Field[1].CurvesList = {1, 2, 3, 5, 11, 12, 13, 15};
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
Field[5] = Max;               // fine only near the arcs and near the origin
Field[5].FieldsList = {2, 4};
Background Field = 5;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
