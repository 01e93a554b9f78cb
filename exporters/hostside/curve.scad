// A gsr_cad curve for OpenSCAD (2-D), written by gsr_cad's "scad" exporter.
// gsr:comment title
// Modules: gsr_curve(width) = the curve as a 2-D stroke, gsr_control_polygon(width) = its control polygon.
// Customize: openscad -D width=0.5 -D 'part="both"' -D height=2 -o out.stl this_file.scad

// stroke width of the curve
width = 0;  // gsr:data
part = "curve";  // [curve, control_polygon, both]
height = 0;  // > 0: extrude the drawing to this height (for STL)

// samples of the curve, finely enough that every chord stays within 1 % of the default width of it
gsr_curve_points = [];  // gsr:data
gsr_control_points = [];  // gsr:data
gsr_closed = false;  // gsr:data

function gsr_normal(a, b) = let (d = b - a) [-d[1], d[0]] / norm(d);

// OpenSCAD snaps 2-D geometry to a 1/65536 grid, so the modules draw gsr_unit times larger and scale back.
gsr_unit = 1;  // gsr:data

// The stroke: one rectangle per chord (offset by width / 2 on both sides) and bevel joins between them (and at
// the seam of a closed curve, whose samples end on the first); their union is right even where the curve
// crosses itself.
module gsr_curve(width = width) {
  p = gsr_unit * gsr_curve_points;
  h = gsr_unit * width / 2;
  scale(1 / gsr_unit) union() {
    for (i = [0:len(p) - 2]) let (n = h * gsr_normal(p[i], p[i + 1]))
      polygon([p[i] + n, p[i + 1] + n, p[i + 1] - n, p[i] - n]);
    for (i = [1:len(p) - 2]) let (a = h * gsr_normal(p[i - 1], p[i]), b = h * gsr_normal(p[i], p[i + 1]))
      gsr_join(p[i], a, b, h);
    if (gsr_closed) let (m = len(p)) gsr_join(p[0], h * gsr_normal(p[m - 2], p[m - 1]), h * gsr_normal(p[0], p[1]), h);
  }
}

// the bevel join at q between chords offset by a (before) and b (after)
module gsr_join(q, a, b, h) {
  if (norm(a - b) > 1e-9 * h) {
    polygon([q, q + a, q + b]);
    polygon([q, q - b, q - a]);
  }
}

module gsr_control_polygon(width = width / 3) {
  p = gsr_unit * gsr_control_points;
  scale(1 / gsr_unit) for (i = [0:len(p) - 2])
    hull() {
      translate(p[i]) circle(d = gsr_unit * width, $fn = 16);
      translate(p[i + 1]) circle(d = gsr_unit * width, $fn = 16);
    }
}

module gsr_drawing() {
  if (part != "control_polygon") color("red") gsr_curve();
  if (part == "control_polygon" || part == "both") color("gray") gsr_control_polygon();
}

if (height > 0) linear_extrude(height = height) gsr_drawing();
else gsr_drawing();
