// The paper's block (80 mm x 40 mm, A at the origin, 20 x 10 cells of 4 mm, one diagonal each) on a
// plate 120 mm x 10 mm whose top y = 0 carries the block; the plate's top under the block has the
// block's 21 nodes (a conforming interface), its two ends are meshed freely. The two bodies share
// no node: the block's AB and the plate's "top" are separate curves at the same place.
L = 80; H = 40; nx = 20; ny = 10;
Point(1) = {0, 0, 0}; Point(2) = {L, 0, 0}; Point(3) = {L, H, 0}; Point(4) = {0, H, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Transfinite Curve {1, 3} = nx + 1;
Transfinite Curve {2, 4} = ny + 1;
Transfinite Surface {1} = {1, 2, 3, 4} Right;
Physical Curve("AB") = {1};
Physical Curve("CD") = {3};
Physical Curve("lateral") = {2, 4};
Physical Surface("block") = {1};

W = 20; T = 10; h = 4;                 // the plate's overhang each side, its thickness, element size
Point(11) = {-W, -T, 0, h}; Point(12) = {L + W, -T, 0, h}; Point(13) = {L + W, 0, 0, h};
Point(14) = {L, 0, 0, h}; Point(15) = {0, 0, 0, h}; Point(16) = {-W, 0, 0, h};
Line(11) = {11, 12}; Line(12) = {12, 13}; Line(13) = {13, 14}; Line(14) = {14, 15}; Line(15) = {15, 16};
Line(16) = {16, 11};
Curve Loop(2) = {11, 12, 13, 14, 15, 16};
Plane Surface(2) = {2};
Transfinite Curve {14} = nx + 1;
Physical Curve("plate_top") = {13, 14, 15};
Physical Curve("plate_bottom") = {11};
Physical Surface("plate") = {2};
