"""Kernels: max-ent approximants, quadrature, node sets, CVT, the energy
functionals and initial shapes. numpy and scipy only: no PETSc, no MPI."""
