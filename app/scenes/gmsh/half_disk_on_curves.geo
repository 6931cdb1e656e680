// The half-disk of half_disk_curved.geo (radius 20 mm, centre (0, 20), its arc touching the origin)
// and two rigid obstacle curves of their own (bounding no surface, so not part of the body), each
// touching the disk at the origin:
// "cylinder", a circle arc of radius 60 mm (centre (0, -60)) from left to right (the body on its
// left), the geometry of half_disk_cylinder.yaml;
// "ellipse", an arc of the ellipse of semi-axes 45 mm (x) and 30 mm (y), centre (0, -30), radius of
// curvature a^2/b = 67.5 mm at the top and smaller away from it.
R = 20; h = 0.5; H = 4.0;
Point(1) = {0, R, 0, H}; Point(2) = {-R, R, 0, H}; Point(3) = {0, 0, 0, h}; Point(4) = {R, R, 0, H};
Circle(1) = {2, 1, 3}; Circle(2) = {3, 1, 4}; Line(3) = {4, 2};
Curve Loop(1) = {1, 2, 3};
Plane Surface(1) = {1};
Field[1] = Distance; Field[1].NodesList = {3};
Field[2] = Threshold; Field[2].IField = 1; Field[2].LcMin = h; Field[2].LcMax = H;
Field[2].DistMin = 6.0; Field[2].DistMax = 14.0;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0; Mesh.MeshSizeFromPoints = 0; Mesh.MeshSizeFromCurvature = 0;
Physical Curve("arc") = {1, 2};
Physical Curve("top") = {3};
Physical Surface("disk") = {1};
// the cylinder: a 100-degree arc through the origin
Rc = 60;
Point(11) = {0, -Rc, 0, H}; Point(12) = {-Rc * Sin(50 * Pi / 180), -Rc + Rc * Cos(50 * Pi / 180), 0, H};
Point(13) = {0, 0, 0, H}; Point(14) = {Rc * Sin(50 * Pi / 180), -Rc + Rc * Cos(50 * Pi / 180), 0, H};
Circle(11) = {12, 11, 13}; Circle(12) = {13, 11, 14};
Physical Curve("cylinder") = {11, 12};
// the ellipse: parametric angles 30 to 90 to 150 degrees, counter-clockwise (from right to left: the
// body is on its right), in two arcs (gmsh's built-in kernel fits an arc's semi-axes to its two end
// points, which must not be symmetric about the axes)
a = 45; b = 30;
Point(21) = {0, -b, 0, H}; Point(22) = {a * Cos(150 * Pi / 180), -b + b * Sin(150 * Pi / 180), 0, H};
Point(23) = {a * Cos(30 * Pi / 180), -b + b * Sin(30 * Pi / 180), 0, H}; Point(24) = {a, -b, 0, H};
Point(25) = {0, 0, 0, H};
Ellipse(21) = {23, 21, 24, 25}; Ellipse(22) = {25, 21, 24, 22};
Physical Curve("ellipse") = {21, 22};
