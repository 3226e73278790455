// Hertz contact of two cylinders of radii R1 = 1 and R2 = 2 touching at the origin (2D,
// plane strain), the half x >= 0 of both (symmetry about x = 0):
//   upper body: the quarter disc x >= 0, y <= R1, x^2 + (y - R1)^2 <= R1^2 (the lower half of
//     the disc of radius R1 centred at (0, R1), cut along its diameter y = R1);
//   lower body: the quarter disc x >= 0, y >= -R2, x^2 + (y + R2)^2 <= R2^2 (the upper half
//     of the disc of radius R2 centred at (0, -R2), cut along its diameter y = -R2).
// The two bodies are separate meshes: they share no node (not even the origin, where both
// have a vertex) and their meshes do not match along the arcs.
// Physical groups (cells): "upper" (physical surface 10), "lower" (11).
// Physical groups (curves):
//   "upper_top"    y = R1, the flat side of the upper body (the load)
//   "upper_sym"    x = 0 of the upper body (symmetry roller u_x = 0)
//   "upper_arc"    the upper arc within "theta1" of its bottom point (the contact surface)
//   "upper_free"   the rest of the upper arc (free)
//   "lower_bottom" y = -R2, the flat side of the lower body (clamped)
//   "lower_sym"    x = 0 of the lower body (symmetry roller u_x = 0)
//   "lower_arc"    the lower arc within "theta2" of its top point (the target)
//   "lower_free"   the rest of the lower arc (free)
// Mesh size: hc on both arcs within "zone" of the origin, growing linearly (rate "grow")
// away from the arcs and, beyond "zone", from the origin, up to hmax; mesh.size scales every
// size.  Sized for a contact half-width a up to about 0.12 (Hertz: a = 0.1 with, e.g.,
// E1 = 1000, nu1 = 0.3, E2 = 2000, nu2 = 0.3 at P = 8.63 N/m per unit length of the whole
// cylinder): a = 0.1 spans 50 cells of size hc on each surface.
hc = 0.002;     // cell size on the contact zone
hmax = 0.08;    // cell size far from it
grow = 0.12;    // size increase per unit distance
zone = 0.25;    // radius (about the origin) of the finely meshed part of the arcs
R1 = 1.0;       // radius of the upper cylinder
R2 = 2.0;       // radius of the lower cylinder
theta1 = 30 * Pi / 180;   // angle of the contact arc "upper_arc" from the bottom point
theta2 = 40 * Pi / 180;   // angle of the target arc "lower_arc" from the top point
Geometry.AutoCoherence = 0;   // the two vertices at the origin stay two points

// upper body
Point(1) = {0, 0, 0};                                        // bottom point: first contact
Point(2) = {R1 * Sin(theta1), R1 - R1 * Cos(theta1), 0};     // end of the contact arc
Point(3) = {R1, R1, 0};
Point(4) = {0, R1, 0};                                       // centre
Circle(1) = {1, 4, 2};        // upper_arc
Circle(2) = {2, 4, 3};        // upper_free
Line(3) = {3, 4};             // upper_top
Line(4) = {4, 1};             // upper_sym
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};

// lower body
Point(11) = {0, 0, 0};                                       // top point: first contact
Point(12) = {R2 * Sin(theta2), -R2 + R2 * Cos(theta2), 0};   // end of the target arc
Point(13) = {R2, -R2, 0};
Point(14) = {0, -R2, 0};                                     // centre
Circle(11) = {11, 14, 12};    // lower_arc
Circle(12) = {12, 14, 13};    // lower_free
Line(13) = {13, 14};          // lower_bottom
Line(14) = {14, 11};          // lower_sym
Curve Loop(11) = {-11, -12, -13, -14};
Plane Surface(11) = {11};

Physical Curve("upper_arc", 1) = {1};
Physical Curve("upper_free", 2) = {2};
Physical Curve("upper_top", 3) = {3};
Physical Curve("upper_sym", 4) = {4};
Physical Curve("lower_arc", 5) = {11};
Physical Curve("lower_free", 6) = {12};
Physical Curve("lower_bottom", 7) = {13};
Physical Curve("lower_sym", 8) = {14};
Physical Surface("upper", 10) = {1};
Physical Surface("lower", 11) = {11};

Field[1] = Distance;          // distance to the two arcs
Field[1].CurvesList = {1, 2, 11, 12};
Field[1].NumPointsPerCurve = 4000;
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
