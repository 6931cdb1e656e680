// The paper's block (80 mm x 40 mm, 20 x 10 cells, one diagonal each) on a rubber pad 120 mm x 20 mm
// meshed on its own (element size 3 mm: the interface's meshes do not match). The two bodies share
// no node: the block's AB and the pad's "pad_top" are separate curves at the same place.
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

W = 20; T = 20; h = 3;                 // the pad's overhang each side, its thickness, element size
Point(11) = {-W, -T, 0, h}; Point(12) = {L + W, -T, 0, h}; Point(13) = {L + W, 0, 0, h};
Point(14) = {-W, 0, 0, h};
Line(11) = {11, 12}; Line(12) = {12, 13}; Line(13) = {13, 14}; Line(14) = {14, 11};
Curve Loop(2) = {11, 12, 13, 14};
Plane Surface(2) = {2};
Physical Curve("pad_top") = {13};
Physical Curve("pad_bottom") = {11};
Physical Surface("pad") = {2};
