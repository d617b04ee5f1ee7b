// Turn blob.stl (a closed triangle surface, metres) into tets with Gmsh's command line:
//   /work/user_scenes/venv/bin/python /work/user_scenes/venv/bin/gmsh blob_to_tets.geo \
//       -3 -nt 1 -format msh41 -o blob_tets.msh
// (the wheel's `gmsh` is a Python script with `#!/usr/bin/env python`: run it with the
// venv's python, not by its shebang). Relative paths in Merge are relative to this file.
// The STL triangles are kept as the boundary (no reparametrisation): only the volume is
// meshed, at most H (in the STL's units: H = 0.006 for a mm STL runs away, give 6).
// Works whatever the STL's triangle orientation (checked with flipped triangles). An open
// STL still exits 0 ("Warning : No tetrahedra in region 1"): the .msh then holds no tets
// (no $Nodes/$Elements at all), so count the tets of the output; exit codes prove nothing.
// Gmsh's t13 route (ClassifySurfaces{40*Pi/180, 1, 1, Pi}; CreateGeometry; before the
// Surface Loop) remeshes the surface instead, and fails on mixed orientations.
H = 0.006;
Mesh.MeshSizeMax = H;
Mesh.Algorithm3D = 1;
General.NumThreads = 1;
Merge "blob.stl";
Surface Loop(1) = Surface{:};
Volume(1) = {1};
Physical Volume("water") = {1};
