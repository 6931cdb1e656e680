// An L-shaped body: a foot 60 mm x 15 mm on the obstacle, an arm 20 mm wide up to 60 mm on its left.
// Its top is held and moved; the foot's bottom may touch the obstacle.
h = 2.5;
Point(1) = {0, 0, 0, h}; Point(2) = {60, 0, 0, h}; Point(3) = {60, 15, 0, h};
Point(4) = {20, 15, 0, h}; Point(5) = {20, 60, 0, h}; Point(6) = {0, 60, 0, h};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 5}; Line(5) = {5, 6}; Line(6) = {6, 1};
Curve Loop(1) = {1, 2, 3, 4, 5, 6};
Plane Surface(1) = {1};
Physical Curve("bottom") = {1};
Physical Curve("top") = {5};
Physical Curve("free") = {2, 3, 4, 6};
Physical Surface("body") = {1};
