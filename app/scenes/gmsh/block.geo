// The block of Villechaise and Zeghloul (docs/method.md section 5): 80 mm x 40 mm, A at the origin.
// Structured 20 x 10 cells of 4 mm, each cut by one diagonal (the built-in pattern "right"/"left").
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
