// Elastic half-disk of radius 20 mm, flat side on top, its arc touching the origin (centre (0, 20)):
// the body of the curved-obstacle examples (half_disk_cylinder.yaml, half_disk_seat.yaml).
// Mesh size h near the first contact point, H away from it.
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
