// The block of Villechaise and Zeghloul (docs/method.md section 5), 80 mm x 40 mm, A at the origin,
// meshed for the final state of its drag in plane strain (nu = 0.48): a stick zone at A about
// 0.045 mm wide, then slip to about 61 mm, then lift-off (docs/validation.md, "The stick zone at A
// resolved"). The element size is the smallest of
//   - hc within 0.1 mm of A and B, growing linearly with the distance to h0 at 20 mm;
//   - 2 mm within AB's neighbourhood, growing to h0 at 10 mm from AB (the lift-off point);
//   - hz at xe, the end of the stick zone, growing by half the distance from it.
// The last term is there because the critical mu of the final state depends on where its stick
// zone ends: one node more or less in the zone moves it by 1.5 to 5 per mm of the zone's width
// (0.0002 to 0.0006 for the 0.00013 mm node spacing at xe at size factor 1), which on a mesh fine
// at the corners alone scatters the values by +-0.4 %. xe is the zone's end found by a first run on the corner-graded mesh (0.0438 mm; the
// finer levels move it to 0.0450). A refinement's size factor scales every size, hz and the rate
// of growth included.
L = 80; H = 40; h0 = 4; hc = 0.016; hab = 2; hz = 0.0001; xe = 0.0438;
Point(1) = {0, 0, 0, h0}; Point(2) = {L, 0, 0, h0}; Point(3) = {L, H, 0, h0}; Point(4) = {0, H, 0, h0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Field[1] = Distance; Field[1].NodesList = {1, 2};
Field[2] = Threshold; Field[2].IField = 1; Field[2].LcMin = hc; Field[2].LcMax = h0;
Field[2].DistMin = 0.1; Field[2].DistMax = 20;
Field[3] = Distance; Field[3].CurvesList = {1}; Field[3].NumPointsPerCurve = 2000;
Field[4] = Threshold; Field[4].IField = 3; Field[4].LcMin = hab; Field[4].LcMax = h0;
Field[4].DistMin = 0; Field[4].DistMax = 10;
Field[5] = MathEval; Field[5].F = Sprintf("%g + 0.5 * Sqrt((x - %g)^2 + y^2)", hz, xe);
Field[6] = Min; Field[6].FieldsList = {2, 4, 5};
Background Field = 6;
Mesh.CharacteristicLengthExtendFromBoundary = 0;
Physical Curve("AB") = {1};
Physical Curve("CD") = {3};
Physical Curve("lateral") = {2, 4};
Physical Surface("block") = {1};
