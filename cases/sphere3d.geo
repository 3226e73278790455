// Hertz contact of a sphere: the eighth of the ball of radius R = 1 centred at (0, 0, 1) with
// x >= 0, y >= 0, z <= 1 (its lower quarter-hemisphere), touching the plane z = 0 at its
// pole (0, 0, 0).
// Physical groups: "surface" the spherical part (contact), "top" the face z = 1, "symx" the
// face x = 0, "symy" the face y = 0 (symmetry rollers), "body" the volume.
// Mesh size: hc within "zone" of the pole, growing linearly to hmax; mesh.size scales it.
SetFactory("OpenCASCADE");
hc = 0.02;      // cell size at the pole
hmax = 0.15;    // cell size far from it
zone = 0.25;    // radius of the ball of size hc around the pole
grow = 0.3;     // size increase per unit distance beyond it
R = 1;

Sphere(1) = {0, 0, R, R};
Box(2) = {0, 0, 0, R, R, R};
BooleanIntersection(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };

e = 1e-6 * R;
top() = Surface In BoundingBox{-e, -e, R - e, R + e, R + e, R + e};
symx() = Surface In BoundingBox{-e, -e, -e, e, R + e, R + e};
symy() = Surface In BoundingBox{-e, -e, -e, R + e, e, R + e};
surface() = Abs(Boundary{ Volume{3}; });
surface() -= {top(), symx(), symy()};
pole() = Point In BoundingBox{-e, -e, -e, e, e, e};

Physical Surface("surface", 1) = {surface()};
Physical Surface("top", 2) = {top()};
Physical Surface("symx", 3) = {symx()};
Physical Surface("symy", 4) = {symy()};
Physical Volume("body", 10) = {3};

Field[1] = Distance;          // distance to the pole
Field[1].PointsList = {pole()};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = hc;
Field[2].SizeMax = hmax;
Field[2].DistMin = zone;
Field[2].DistMax = zone + (hmax - hc) / grow;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
