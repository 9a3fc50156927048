"""Geometry and meshes: gmsh body shapes, built-in EM geometries, EM mesh motion, remesh, shared meshes."""
