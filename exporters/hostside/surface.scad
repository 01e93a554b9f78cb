// A gsr_cad Catmull-Clark surface for OpenSCAD (3-D), written by gsr_cad's "scad" exporter.
// gsr:comment title
// Modules: gsr_limit_surface() = the Catmull-Clark limit surface (vertices on the limit) as a polyhedron;
// gsr_control_cage(width) = the edges of the control mesh; gsr_control_solid() = the control mesh as a
// polyhedron. By default only the limit surface is drawn. The history that built the control mesh:
// gsr:comment history
// Customize: openscad -D 'part="both"' -o out.stl this_file.scad

part = "surface";  // [surface, cage, cage_solid, both]
place = true;  // false: draw the model about the origin (coordinates below are relative to gsr_centre)

// thickness of the cage's edges
width = 0;  // gsr:data
gsr_centre = [0, 0, 0];  // gsr:data

// limit mesh: triangles clockwise seen from outside, as OpenSCAD wants
gsr_limit_points = [];  // gsr:data
gsr_limit_faces = [];  // gsr:data

// control mesh: faces clockwise seen from outside, and its edges
gsr_cage_points = [];  // gsr:data
gsr_cage_faces = [];  // gsr:data
gsr_cage_edges = [];  // gsr:data

module gsr_limit_surface() {
  polyhedron(points = gsr_limit_points, faces = gsr_limit_faces, convexity = 10);
}

module gsr_control_solid() {
  polyhedron(points = gsr_cage_points, faces = gsr_cage_faces, convexity = 10);
}

module gsr_control_cage(width = width) {
  for (e = gsr_cage_edges)
    hull() {
      translate(gsr_cage_points[e[0]]) sphere(d = width, $fn = 8);
      translate(gsr_cage_points[e[1]]) sphere(d = width, $fn = 8);
    }
}

module gsr_model() {
  if (part == "both" || part == "surface") color("gold") gsr_limit_surface();
  if (part == "both" || part == "cage") color("dimgray") gsr_control_cage();
  if (part == "cage_solid") gsr_control_solid();
}

if (place) translate(gsr_centre) gsr_model();
else gsr_model();
