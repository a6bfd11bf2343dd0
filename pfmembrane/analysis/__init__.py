"""Analysis of solutions: phi_h and its level set, the sharp-interface
solver, the sharp limit, plots. Usable without petsc4py."""
