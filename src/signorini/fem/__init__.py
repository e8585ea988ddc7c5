"""The discretisation: meshes and mesh files, plane-strain and axisymmetric
kinematics, the element kernels, loads and supports, sparse assembly."""
