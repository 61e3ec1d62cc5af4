// The fluid domain of the tutorial (README, "Tutorial"): a channel 8 long and 1 high, meshed
// finer where the leaflet hangs (x = 4). `gmsh -2 channel.geo` writes channel.msh.
// The fluid mesh covers the leaflet: fdfsi adapts it to the leaflet at every step.
L = 8;          // length
H = 1;          // height
h_far = 0.1;    // cell size away from the leaflet
h_near = 0.025; // cell size where the leaflet moves

Point(1) = {0, 0, 0, h_far};
Point(2) = {L, 0, 0, h_far};
Point(3) = {L, H, 0, h_far};
Point(4) = {0, H, 0, h_far};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};

// h_near in the box 3.5 <= x <= 5, growing to h_far over 0.5 outside it.
Field[1] = Box;
Field[1].VIn = h_near;
Field[1].VOut = h_far;
Field[1].XMin = 3.5;
Field[1].XMax = 5.0;
Field[1].YMin = 0;
Field[1].YMax = H;
Field[1].Thickness = 0.5;
Background Field = 1;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;

// Straight sides: 3-node triangles (fdfsi builds the P2+ nodes itself).
Mesh.ElementOrder = 1;

// The names the case file's [[boundary]] tables use.
Physical Curve("bottom") = {1};
Physical Curve("outlet") = {2};
Physical Curve("top") = {3};
Physical Curve("inlet") = {4};
Physical Surface("fluid") = {1};
