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

function gsr_normal(a, b) = let (d = b - a) [-d[1], d[0]] / norm(d);

// OpenSCAD snaps 2-D geometry to a 1/65536 grid, so the modules draw gsr_unit times larger and scale back.
gsr_unit = 1;  // gsr:data

// The stroke: one rectangle per chord (offset by width / 2 on both sides) and bevel joins between them;
// their union is right even where the curve crosses itself.
module gsr_curve(width = width) {
  p = gsr_unit * gsr_curve_points;
  h = gsr_unit * width / 2;
  scale(1 / gsr_unit) union() {
    for (i = [0:len(p) - 2]) let (n = h * gsr_normal(p[i], p[i + 1]))
      polygon([p[i] + n, p[i + 1] + n, p[i + 1] - n, p[i] - n]);
    for (i = [1:len(p) - 2]) let (a = h * gsr_normal(p[i - 1], p[i]), b = h * gsr_normal(p[i], p[i + 1]))
      if (norm(a - b) > 1e-9 * h) {
        polygon([p[i], p[i] + a, p[i] + b]);
        polygon([p[i], p[i] - b, p[i] - a]);
      }
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
