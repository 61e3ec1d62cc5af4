// The solid of the tutorial (README, "Tutorial"): a leaflet 0.05 thick hanging 0.5 down from
// the channel's top wall at x = 4, in 2 x 10 9-node quadrilaterals (fdfsi's solid element is
// Q2). `gmsh -2 leaflet.geo` writes leaflet.msh.
x0 = 3.975; // upstream face
x1 = 4.025; // downstream face
y0 = 0.5;   // tip
y1 = 1.0;   // on the top wall

Point(1) = {x0, y0, 0};
Point(2) = {x1, y0, 0};
Point(3) = {x1, y1, 0};
Point(4) = {x0, y1, 0};
Line(1) = {1, 2}; // the tip
Line(2) = {2, 3}; // the downstream face
Line(3) = {3, 4}; // on the wall
Line(4) = {4, 1}; // the upstream face
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};

// A structured grid of quadrilaterals: 2 cells across, 10 along.
Transfinite Curve{1, 3} = 3;
Transfinite Curve{2, 4} = 11;
Transfinite Surface{1};
Recombine Surface{1};
Mesh.ElementOrder = 2;
Mesh.SecondOrderIncomplete = 0; // 9-node, not 8-node, quadrilaterals

Physical Curve("tip") = {1};
Physical Curve("downstream") = {2};
Physical Curve("top") = {3};
Physical Curve("upstream") = {4};
Physical Surface("leaflet") = {1};
