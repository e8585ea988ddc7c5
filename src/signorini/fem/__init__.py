"""The discretisation: meshes and mesh files, plane-strain and axisymmetric
kinematics, the element kernels, loads and supports, sparse assembly; the
three-dimensional cells (hexahedra, tetrahedra) and their meshes."""
