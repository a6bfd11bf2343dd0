"""Input and output: HDF5 checkpoints (with their XDMF sidecar) and the
application options. No PETSc at import."""
