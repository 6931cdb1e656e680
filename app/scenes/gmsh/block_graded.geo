// The block of Villechaise and Zeghloul (docs/method.md section 5), 80 mm x 40 mm, A at the origin,
// meshed finely at the corners A and B of the contact side: element size hc there, growing linearly
// with the distance to h0 at 20 mm. The final state of the drag in plane strain has a stick zone
// about 0.045 mm wide at A, which a uniform mesh sees as one node (docs/validation.md, "Plane strain
// with the mixed element"); hc = 0.008 mm puts about eight nodes in it.
L = 80; H = 40; hc = 0.008; h0 = 4;
Point(1) = {0, 0, 0, h0}; Point(2) = {L, 0, 0, h0}; Point(3) = {L, H, 0, h0}; Point(4) = {0, H, 0, h0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Field[1] = Distance; Field[1].NodesList = {1, 2};
Field[2] = Threshold; Field[2].IField = 1; Field[2].LcMin = hc; Field[2].LcMax = h0;
Field[2].DistMin = 0; Field[2].DistMax = 20;
Background Field = 2;
Mesh.CharacteristicLengthExtendFromBoundary = 0;
Physical Curve("AB") = {1};
Physical Curve("CD") = {3};
Physical Curve("lateral") = {2, 4};
Physical Surface("block") = {1};
