//! Meshes built in code: spheres, tori, boxes, thin shells, assemblies.
