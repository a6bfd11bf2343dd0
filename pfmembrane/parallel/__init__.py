"""The PETSc layer: node partition, the grid's distributed operators,
assembly into Vec/Mat, and the two-stage solver."""
