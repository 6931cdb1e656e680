// A block 40 mm x 20 mm resting on a plane inclined at 25 degrees (rising to the right),
// its base on the line through the origin.
alpha = 25 * Pi / 180; L = 40; H = 20; h = 4;
Point(1) = {0, 0, 0, h}; Point(2) = {L, 0, 0, h}; Point(3) = {L, H, 0, h}; Point(4) = {0, H, 0, h};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Rotate {{0, 0, 1}, {0, 0, 0}, alpha} { Surface{1}; }
Transfinite Curve {1, 3} = L / h + 1;
Transfinite Curve {2, 4} = H / h + 1;
Transfinite Surface {1};
Physical Curve("base") = {1};
Physical Curve("sides") = {2, 3, 4};
Physical Surface("block") = {1};
